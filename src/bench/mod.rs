//! `stereotrace bench`: measurements of method choices.
//! - `accel`: kd-tree build time and ray throughput per split strategy, with baselines on the
//!   identical rays;
//! - `sweep`: a pipeline rendered for every combination of swept keys, timed and compared with a
//!   high-quality render of the same frames;
//! - `chart`: both tables drawn as speed against accuracy with their Pareto fronts;
//! - `memory`: the peak-heap counter the sweep reports.

pub mod accel;
#[cfg(feature = "gpu")]
mod accel_gpu;
mod accel_options;
mod accel_table;
mod chart;
pub mod memory;
mod rays;
pub mod sweep;

/// The median of measurements (the mean of the middle two for an even count; NaN for none).
pub(crate) fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}
