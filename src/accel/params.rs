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

/// Build constants. Defaults: K_T = 15, K_I = 20 and an empty-space factor of 0.8 (a cost
/// bonus of 0.2) as Wald & Havran (RT'06) give them and Mitsuba uses; the depth cap is pbrt-v3's
/// `8 + 1.3 log2 N`, only a safety net since the SAH termination criterion ends the recursion.
#[derive(Clone, Copy, Debug)]
pub struct BuildParams {
    pub method: SplitMethod,
    pub traversal_cost: f32,
    pub intersection_cost: f32,
    pub empty_bonus: f32,
    /// Center and median stop at this many triangles (they have no cost model).
    pub leaf_size: usize,
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            method: SplitMethod::Sah,
            traversal_cost: 15.0,
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
}
