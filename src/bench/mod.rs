//! `stereotrace bench`: measurements of method choices.
//! - `accel`: kd-tree build time and ray throughput per split strategy, with baselines on the
//!   identical rays;
//! - `sweep`: a pipeline rendered for every combination of swept keys, timed and compared with a
//!   high-quality render of the same frames;
//! - `chart`: both tables drawn as speed against accuracy with their Pareto fronts;
//! - `memory`: the peak-heap counter the sweep reports.

pub mod accel;
pub mod chart;
pub mod memory;
pub mod sweep;
