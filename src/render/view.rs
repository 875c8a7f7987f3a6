//! Views: the points along the rig's baseline a frame is traced from. The two eyes, the centre
//! eye of a mono rig, and the intermediate views a wobble GIF adds between the eyes. A view knows
//! its name (EXR views, file names, the frame log), its place on the baseline, and its sampling
//! seed; the camera of a view is made in one place, `EyeCamera::new`.

use super::sampling::hash32;
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Eye {
    Left,
    Right,
    /// The mono render.
    Center,
}

impl Eye {
    pub fn name(self) -> &'static str {
        match self {
            Eye::Left => "left",
            Eye::Right => "right",
            Eye::Center => "center",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum View {
    Eye(Eye),
    /// View `index` of `count` evenly spaced along the baseline, strictly between the eyes
    /// (`0 < index < count - 1`; the ends are the eyes themselves).
    Between {
        index: usize,
        count: usize,
    },
}

impl View {
    pub const LEFT: View = View::Eye(Eye::Left);
    pub const RIGHT: View = View::Eye(Eye::Right);
    pub const CENTER: View = View::Eye(Eye::Center);

    /// View `i` of `n` evenly spaced along the baseline, left to right.
    pub fn along_baseline(i: usize, n: usize) -> View {
        if i == 0 {
            View::LEFT
        } else if i + 1 >= n {
            View::RIGHT
        } else {
            View::Between { index: i, count: n }
        }
    }

    pub fn name(&self) -> String {
        match self {
            View::Eye(e) => e.name().to_string(),
            View::Between { index, count } => format!("wobble-{index}-of-{count}"),
        }
    }

    /// Signed place on the baseline as a fraction of the interaxial distance: -1/2 the left
    /// eye, +1/2 the right, 0 the centre.
    pub fn offset_fraction(&self) -> f32 {
        match self {
            View::Eye(Eye::Left) => -0.5,
            View::Eye(Eye::Right) => 0.5,
            View::Eye(Eye::Center) => 0.0,
            View::Between { index, count } => -0.5 + *index as f32 / (*count - 1) as f32,
        }
    }

    /// Sampling seed: the eyes keep their historical seeds (0, 1, 2) so stored regression clips
    /// stay valid; intermediate views hash their name.
    pub fn seed(&self) -> u32 {
        match self {
            View::Eye(e) => *e as u32,
            View::Between { .. } => self
                .name()
                .bytes()
                .fold(0x5eed_u32, |h, b| hash32(h ^ b as u32)),
        }
    }

    /// The order a frame's views are traced in: left, right, centre, then the intermediate views
    /// left to right.
    pub fn trace_order(&self, other: &View) -> Ordering {
        let rank = |v: &View| match v {
            View::Eye(e) => *e as u8,
            View::Between { .. } => 3,
        };
        rank(self)
            .cmp(&rank(other))
            .then(self.offset_fraction().total_cmp(&other.offset_fraction()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_along_the_baseline_end_at_the_eyes() {
        assert_eq!(View::along_baseline(0, 3), View::LEFT);
        assert_eq!(View::along_baseline(2, 3), View::RIGHT);
        let mid = View::along_baseline(1, 3);
        assert_eq!(mid.name(), "wobble-1-of-3");
        assert_eq!(mid.offset_fraction(), 0.0);
        assert_eq!(View::along_baseline(1, 5).offset_fraction(), -0.25);
    }

    #[test]
    fn eyes_keep_their_historical_seeds() {
        assert_eq!(
            [View::LEFT, View::RIGHT, View::CENTER].map(|v| v.seed()),
            [0, 1, 2]
        );
    }
}
