//! `bench accel --backend gpu`: the kd-tree each repeat builds, uploaded and walked on the GPU
//! with each published walk, on the same rays as the CPU rows of the same run. Rows are
//! `METHOD+gpu-WALK` with the adapter in the `device` column, and the walk's work per ray (inner
//! nodes, leaves, triangle tests) from an untimed counted pass.

use super::accel_table::AccelRow;
use crate::accel::{Hit, KdTree, Ray};
use crate::error::Result;
use crate::gpu::{Gpu, GpuAccel, GpuRays, GpuTracer, GpuWalk};

/// What tracing found: rays that hit (or were occluded) and the sum of their hit distances.
pub(super) type Found = (u64, f64);

/// A GPU row's measurements: seconds per primary and per shadow pass, and what the last found.
pub(super) struct GpuRun {
    pub row: AccelRow,
    pub primary_s: Vec<f64>,
    pub shadow_s: Vec<f64>,
    pub primary_found: Found,
    pub shadow_found: Found,
}

/// The adapter, its compiled walks and one scene's rays, resident for the whole scene.
pub(super) struct GpuBench {
    gpu: Gpu,
    tracer: GpuTracer,
    primary: GpuRays,
    shadow: GpuRays,
}

fn found(hits: &[Option<Hit>]) -> Found {
    hits.iter()
        .flatten()
        .fold((0, 0.0), |(n, sum), h| (n + 1, sum + h.t as f64))
}

impl GpuBench {
    /// Opens the adapter (its description goes to `log`, with a warning when it is software)
    /// and uploads both ray sets.
    pub fn new(
        primary: (&[Ray], &[f32]),
        shadow: (&[Ray], &[f32]),
        log: &mut dyn FnMut(String),
    ) -> Result<GpuBench> {
        let gpu = Gpu::open()?;
        log(format!("GPU adapter: {}", gpu.describe()));
        if gpu.is_software() {
            log(
                "GPU adapter runs on the CPU: its rows check correctness, not a GPU's speed".into(),
            );
        }
        let tracer = GpuTracer::new(&gpu)?;
        let primary = GpuRays::upload(&gpu, primary.0, primary.1)?;
        let shadow = GpuRays::upload(&gpu, shadow.0, shadow.1)?;
        Ok(GpuBench {
            gpu,
            tracer,
            primary,
            shadow,
        })
    }

    /// One row per walk, named after `template`'s method.
    pub fn runs(&self, template: &AccelRow) -> Vec<GpuRun> {
        GpuWalk::ALL
            .iter()
            .map(|w| GpuRun {
                row: AccelRow {
                    method: format!("{}+gpu-{}", template.method, w.name()),
                    device: Some(self.gpu.info.name.clone()),
                    ..template.clone()
                },
                primary_s: Vec::new(),
                shadow_s: Vec::new(),
                primary_found: (0, 0.0),
                shadow_found: (0, 0.0),
            })
            .collect()
    }

    /// Uploads `tree` and times every walk `repeat` times on both ray sets, into `runs`.
    pub fn measure(&self, tree: &KdTree, repeat: u32, runs: &mut [GpuRun]) -> Result<()> {
        let mut on_gpu = GpuAccel::new(&self.gpu)?;
        on_gpu.upload_tree(&self.gpu, tree)?;
        for (run, &walk) in runs.iter_mut().zip(&GpuWalk::ALL) {
            if run.row.primary_work.is_none() {
                let (t, g) = (&self.tracer, &self.gpu);
                run.row.primary_work = Some(t.work(g, &on_gpu, &self.primary, walk, false)?);
                run.row.shadow_work = Some(t.work(g, &on_gpu, &self.shadow, walk, true)?);
            }
        }
        for _ in 0..repeat.max(1) {
            for (run, &walk) in runs.iter_mut().zip(&GpuWalk::ALL) {
                let t = self
                    .tracer
                    .trace(&self.gpu, &on_gpu, &self.primary, walk, false)?;
                run.primary_s.push(t);
                run.primary_found = found(&self.tracer.read_hits(&self.gpu, &self.primary)?);
                let t = self
                    .tracer
                    .trace(&self.gpu, &on_gpu, &self.shadow, walk, true)?;
                run.shadow_s.push(t);
                run.shadow_found = found(&self.tracer.read_hits(&self.gpu, &self.shadow)?);
            }
        }
        Ok(())
    }
}
