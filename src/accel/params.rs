//! What a kd-tree build is asked for: the split strategy and the cost constants, with their
//! defaults in one place (every builder reads them from here).

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum SplitMethod {
    Center,
    Median,
    /// Binned SAH where nodes are large, exact where small (`binned.rs`): the default.
    #[default]
    Sah,
    /// The exact O(N log N) event sweep (`sah.rs`): the reference for the fast build's quality.
    SahExact,
}

/// Build constants. Defaults: K_I = 20 and an empty-space factor of 0.8 (a cost bonus of 0.2)
/// as Wald & Havran (RT'06) give them and Mitsuba uses; K_T = 15 (theirs) for the bounded tree
/// and, for the clipped-reference kd-tree, by the mesh's size (`traversal_cost_for`, measured);
/// the depth cap is pbrt-v3's `8 + 1.3 log2 N`, only a safety net since the SAH termination
/// criterion ends the recursion.
#[derive(Clone, Copy, Debug)]
pub struct BuildParams {
    pub method: SplitMethod,
    pub traversal_cost: f32,
    /// Whether the kd-tree build replaces `traversal_cost` by `traversal_cost_for` its triangle
    /// count (the default); `false` keeps the value given (`bench accel --traversal-cost`).
    pub traversal_by_size: bool,
    pub intersection_cost: f32,
    pub empty_bonus: f32,
    /// Center and median stop at this many triangles (they have no cost model).
    pub leaf_size: usize,
}

/// The SAH's traversal cost for a kd-tree over `triangles` triangles: what a step costs against
/// a triangle test (K_I = 20) grows once the tree outgrows the caches, so larger meshes get
/// larger leaves. Measured with `bench accel --traversal-cost` and whole renders, 2 threads:
/// - up to 32k triangles, 25: with eight-ray packets the Whitted scenes (7,938) rendered
///   `pipelines/default.toml` in 0.474-0.482 s against 0.485-0.491 with 15, and
///   `pipelines/diffuse.toml` in 0.212-0.214 s against 0.214-0.217 (three alternating runs,
///   the images byte-identical); 40 was no better than 15 (0.470-0.489, 0.213-0.222). With
///   four-ray packets 15 had been the best (25-60 traced `diffuse.toml` 6-8% slower);
/// - up to 512k, 60: with eight-ray packets (`bench accel --traversal-cost 40,60,80 --walk
///   single,packet --film 384`, 2 threads, two rounds) bunny (69k) built in 0.032 s against
///   0.045-0.049 with 40, bunny_loop1 (278k) in 0.12-0.16 s against 0.18-0.20 and
///   TransmissionTest (129k) in 0.045-0.057 s against 0.069-0.072, their packets 3-15% faster
///   (but for one round of TransmissionTest's shadow packets, 5% slower) and single rays 0-13%
///   slower (the most, TransmissionTest's camera rays in one round); TransmissionTest's
///   stereo frame at 480x270 traced in 2.06-2.50 s against 2.11-2.77 (five alternating rounds,
///   the images byte-identical), and BrainStem's rebuilt frame updated in 26.3-26.9 ms against
///   37.3-38.5 with its tracing the same. 40 had been the best with four-ray packets
///   (TransmissionTest's frame 8.9-9.0 s against 9.4-9.8 with 15 and 9.0-9.3 with 60);
/// - above, 100: with eight-ray packets, on the 1M peer mesh's rays (`vs-embree.sh`'s), it built
///   in 0.277-0.278 s against 0.361 with 60 (Embree 4: 0.17-0.19 s), and its packets traced
///   19.56-19.88 camera and 9.09-9.18 shadow Mrays/s against 19.31-19.35 and 8.91-9.04;
///   bunny_loop2 (1.1M) built in 0.32-0.33 s against 0.43 and its packets traced 3-9% faster;
///   MetalRoughSpheresNoTextures (1.0M) built in 0.27-0.29 s against 0.36, its camera packets
///   the same and its shadow packets 10-12% slower. Single rays, which take a leaf's triangles
///   one by one, lose: 8-9% on the peer mesh's camera rays, 12-16% on MetalRoughSpheres' shadow
///   rays (two alternating rounds of `bench accel --traversal-cost 60,80,100,115`). 60 had been
///   the best with four-ray packets (12.6 Mrays/s against 10.3 with 15 and 11.9 with 40).
pub fn traversal_cost_for(triangles: usize) -> f32 {
    match triangles {
        0..32_768 => 25.0,
        32_768..524_288 => 60.0,
        _ => 100.0,
    }
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            method: SplitMethod::Sah,
            traversal_cost: 15.0,
            traversal_by_size: true,
            intersection_cost: 20.0,
            empty_bonus: 0.2,
            leaf_size: 4,
        }
    }
}

impl BuildParams {
    pub fn with_method(method: SplitMethod) -> Self {
        BuildParams {
            method,
            ..Default::default()
        }
    }

    /// The constants a kd-tree over `triangles` triangles is built with: the traversal cost
    /// set by the size unless a fixed one was asked for.
    pub fn for_triangles(self, triangles: usize) -> Self {
        BuildParams {
            traversal_cost: if self.traversal_by_size {
                traversal_cost_for(triangles)
            } else {
                self.traversal_cost
            },
            traversal_by_size: false,
            ..self
        }
    }
}
