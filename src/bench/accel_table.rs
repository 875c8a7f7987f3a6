//! The `bench accel` table: one row per scene and method, as CSV (printed while measuring,
//! written with `--csv`, read back by `bench chart-accel`) and as a chart.

use super::chart::{self, Chart, Front, Point, Series};
use crate::error::{Error, Result};
use crate::output::{csv_line, read_csv, write_csv};
use std::path::Path;

#[derive(Clone, Debug, Default)]
pub struct AccelRow {
    pub scene: String,
    pub method: String,
    pub triangles: usize,
    pub threads: usize,
    pub build_s: f64,
    pub build_ns_per_triangle: f64,
    pub primary_mrays_s: f64,
    pub shadow_mrays_s: f64,
    pub sah_cost: Option<f64>,
    pub nodes: Option<usize>,
    pub leaves: Option<usize>,
    pub max_depth: Option<usize>,
    pub refs_per_triangle: Option<f64>,
    pub bytes: Option<usize>,
    /// Primary rays that hit, and their mean hit distance: "the same hits" as a peer, checked.
    pub primary_hits: Option<u64>,
    pub mean_t: Option<f64>,
    /// Shadow rays that found an occluder.
    pub shadow_occluded: Option<u64>,
    /// Per primary ray: inner nodes visited, leaves visited, triangle tests (kd-trees only).
    pub primary_work: Option<[f64; 3]>,
    /// The same per shadow ray.
    pub shadow_work: Option<[f64; 3]>,
    /// The GPU adapter that traced the row (GPU rows only; CPU rows ran on `threads` threads).
    pub device: Option<String>,
}

/// The table's columns. Tables written before the last ten existed still read back.
pub const COLUMNS: [&str; 24] = [
    "scene",
    "method",
    "triangles",
    "threads",
    "build_s",
    "build_ns_per_triangle",
    "primary_mrays_s",
    "shadow_mrays_s",
    "sah_cost",
    "nodes",
    "leaves",
    "max_depth",
    "refs_per_triangle",
    "bytes",
    "primary_hits",
    "mean_t",
    "shadow_occluded",
    "primary_inner_per_ray",
    "primary_leaves_per_ray",
    "primary_tests_per_ray",
    "shadow_inner_per_ray",
    "shadow_leaves_per_ray",
    "shadow_tests_per_ray",
    "device",
];

/// Columns every table has had.
const REQUIRED: usize = 14;

impl AccelRow {
    /// The row's fields in `COLUMNS` order, as written to the table.
    pub fn fields(&self) -> Vec<String> {
        let opt = |v: Option<String>| v.unwrap_or_default();
        let mut f = vec![
            self.scene.clone(),
            self.method.clone(),
            self.triangles.to_string(),
            self.threads.to_string(),
            format!("{:.6}", self.build_s),
            format!("{:.1}", self.build_ns_per_triangle),
            format!("{:.4}", self.primary_mrays_s),
            format!("{:.4}", self.shadow_mrays_s),
            opt(self.sah_cost.map(|v| format!("{v:.2}"))),
            opt(self.nodes.map(|v| v.to_string())),
            opt(self.leaves.map(|v| v.to_string())),
            opt(self.max_depth.map(|v| v.to_string())),
            opt(self.refs_per_triangle.map(|v| format!("{v:.3}"))),
            opt(self.bytes.map(|v| v.to_string())),
            opt(self.primary_hits.map(|v| v.to_string())),
            opt(self.mean_t.map(|v| format!("{v:.6}"))),
            opt(self.shadow_occluded.map(|v| v.to_string())),
        ];
        for work in [self.primary_work, self.shadow_work] {
            for k in 0..3 {
                f.push(opt(work.map(|w| format!("{:.2}", w[k]))));
            }
        }
        f.push(opt(self.device.clone()));
        f
    }

    /// The row as one CSV line (the benchmark prints rows as they are measured).
    pub fn csv(&self) -> String {
        csv_line(&self.fields())
    }
}

/// Charts a `bench accel` table: build time against nanoseconds per primary ray, one series per
/// scene, a Pareto front per scene (scenes of different sizes are not comparable points).
pub fn chart(rows: &[AccelRow], stem: &Path) -> Result<()> {
    let series = Series::group(rows.iter().map(|r| {
        let point = Point {
            label: r.method.clone(),
            x: r.build_s,
            y: 1e3 / r.primary_mrays_s,
        };
        (format!("{} ({} tris)", r.scene, r.triangles), point)
    }));
    chart::write(
        &Chart {
            title: "kd-tree split strategies: build time against trace time".into(),
            x_label: "build time (s)".into(),
            y_label: format!(
                "ns per primary ray ({} threads)",
                rows.first().map_or(0, |r| r.threads)
            ),
            series,
            front: Front::PerSeries,
        },
        stem,
    )
}

/// The header line `bench accel` prints before its rows.
pub fn csv_header() -> String {
    COLUMNS.join(",")
}

/// Writes the table as CSV.
pub fn write_table(path: &Path, rows: &[AccelRow]) -> Result<()> {
    let fields: Vec<Vec<String>> = rows.iter().map(AccelRow::fields).collect();
    write_csv(path, &COLUMNS, &fields)
}

/// Reads a table written by `bench accel --csv` (or its standard output) back.
pub fn read_table(path: &Path) -> Result<Vec<AccelRow>> {
    let (header, rows) = read_csv(path, "bench accel table")?;
    if header.len() < REQUIRED || header.iter().zip(COLUMNS).any(|(h, c)| h != c) {
        return Err(Error::input(
            path,
            "not a bench accel table: the header differs",
        ));
    }
    rows.into_iter()
        .enumerate()
        .map(|(i, f)| {
            let bad = |what: &str| Error::input(path, format!("line {}: {what}", i + 2));
            if f.len() != header.len() {
                return Err(bad("wrong number of fields"));
            }
            let num = |k: usize| {
                f[k].parse::<f64>()
                    .map_err(|_| bad(&format!("'{}' is not a number", f[k])))
            };
            let opt = |k: usize| {
                f.get(k)
                    .filter(|v| !v.is_empty())
                    .and_then(|v| v.parse::<f64>().ok())
            };
            let work = |k: usize| Some([opt(k)?, opt(k + 1)?, opt(k + 2)?]);
            Ok(AccelRow {
                scene: f[0].to_string(),
                method: f[1].to_string(),
                triangles: num(2)? as usize,
                threads: num(3)? as usize,
                build_s: num(4)?,
                build_ns_per_triangle: num(5)?,
                primary_mrays_s: num(6)?,
                shadow_mrays_s: num(7)?,
                sah_cost: opt(8),
                nodes: opt(9).map(|v| v as usize),
                leaves: opt(10).map(|v| v as usize),
                max_depth: opt(11).map(|v| v as usize),
                refs_per_triangle: opt(12),
                bytes: opt(13).map(|v| v as usize),
                primary_hits: opt(14).map(|v| v as u64),
                mean_t: opt(15),
                shadow_occluded: opt(16).map(|v| v as u64),
                primary_work: work(17),
                shadow_work: work(20),
                device: f.get(23).filter(|v| !v.is_empty()).cloned(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_read_back_what_was_written() {
        let rows = [
            AccelRow {
                scene: "bunny".into(),
                method: "sah".into(),
                triangles: 948,
                threads: 2,
                build_s: 0.0115,
                build_ns_per_triangle: 12102.0,
                primary_mrays_s: 19.1684,
                shadow_mrays_s: 6.4806,
                sah_cost: Some(583.91),
                nodes: Some(7055),
                leaves: Some(3528),
                max_depth: Some(21),
                refs_per_triangle: Some(5.026),
                bytes: Some(109628),
                primary_hits: Some(91234),
                mean_t: Some(3.874808),
                shadow_occluded: Some(20600),
                primary_work: Some([41.5, 6.25, 18.0]),
                shadow_work: Some([30.0, 5.5, 21.75]),
                device: None,
            },
            AccelRow {
                scene: "bunny".into(),
                method: "sah+gpu-stack".into(),
                triangles: 948,
                threads: 2,
                primary_mrays_s: 1.25,
                primary_hits: Some(91234),
                device: Some("llvmpipe (LLVM 15.0.6, 256 bits)".into()),
                ..Default::default()
            },
            AccelRow {
                scene: "bunny".into(),
                method: "brute-force".into(),
                triangles: 948,
                threads: 2,
                build_s: 0.0003,
                primary_mrays_s: 0.5,
                ..Default::default()
            },
        ];
        let path = std::env::temp_dir().join(format!("accel-{}.csv", std::process::id()));
        let text: Vec<String> = std::iter::once(csv_header())
            .chain(rows.iter().map(AccelRow::csv))
            .collect();
        std::fs::write(&path, text.join("\n")).unwrap();
        let back = read_table(&path).unwrap();
        assert_eq!(back.len(), 3);
        for (a, b) in rows.iter().zip(&back) {
            assert_eq!(a.csv(), b.csv());
        }
        assert_eq!(
            back[1].device.as_deref(),
            Some("llvmpipe (LLVM 15.0.6, 256 bits)")
        );
        // A table from before the walk columns existed reads back with them empty.
        let old = "scene,method,triangles,threads,build_s,build_ns_per_triangle,primary_mrays_s,shadow_mrays_s,sah_cost,nodes,leaves,max_depth,refs_per_triangle,bytes\nb,sah,9,2,0.1,1.0,2.0,3.0,4.0,5,6,7,8.0,9\n";
        std::fs::write(&path, old).unwrap();
        let back = read_table(&path).unwrap();
        assert_eq!((back[0].nodes, back[0].primary_work), (Some(5), None));
        std::fs::write(&path, "scene,method\nx,y\n").unwrap();
        assert!(
            read_table(&path)
                .unwrap_err()
                .to_string()
                .contains("header")
        );
        std::fs::remove_file(path).unwrap();
    }
}
