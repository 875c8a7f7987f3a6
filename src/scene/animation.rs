//! glTF animations: channels read from the file, and their values at a time `t`. Conventions of
//! DESIGN.md where the specification leaves a choice: every animation starts at t = 0 and does not
//! loop; each sampler clamps to its own key range; rotations are normalized, LINEAR rotation is
//! slerp along the shortest path, CUBICSPLINE results are normalized; when two channels drive the
//! same property the later one (animation order, then channel order) wins.

use super::buffers::check_accessor;
use crate::error::{Error, Result};
use glam::{Quat, Vec3};
use serde::Serialize;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Property {
    Translation,
    Rotation,
    Scale,
    Weights,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

/// One channel with its sampler's data.
#[derive(Clone, Debug)]
pub struct Channel {
    pub node: usize,
    pub property: Property,
    pub interpolation: Interpolation,
    /// Key times in seconds, strictly increasing.
    pub times: Vec<f32>,
    /// Values, `stride` floats per element; CUBICSPLINE stores (in-tangent, value, out-tangent)
    /// per key.
    pub values: Vec<f32>,
    /// Floats per element: 3 (T, S), 4 (R), or the number of morph targets (weights).
    pub stride: usize,
}

#[derive(Clone, Debug)]
pub struct Animation {
    pub name: Option<String>,
    pub channels: Vec<Channel>,
}

/// What a glTF file animates, summarised per kind, for `info` and `check`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct AnimationSummary {
    pub name: Option<String>,
    pub translation_channels: usize,
    pub rotation_channels: usize,
    pub scale_channels: usize,
    pub weight_channels: usize,
    /// Interpolations used (STEP, LINEAR, CUBICSPLINE).
    pub interpolations: Vec<String>,
    /// Last key time in seconds.
    pub duration: f32,
}

impl Animation {
    pub fn summary(&self) -> AnimationSummary {
        let mut s = AnimationSummary {
            name: self.name.clone(),
            ..Default::default()
        };
        for c in &self.channels {
            match c.property {
                Property::Translation => s.translation_channels += 1,
                Property::Rotation => s.rotation_channels += 1,
                Property::Scale => s.scale_channels += 1,
                Property::Weights => s.weight_channels += 1,
            }
            let name = format!("{:?}", c.interpolation).to_uppercase();
            if !s.interpolations.contains(&name) {
                s.interpolations.push(name);
            }
            s.duration = s.duration.max(c.times.last().copied().unwrap_or(0.0));
        }
        s
    }
}

pub(super) fn load_animation(
    file: &Path,
    buffers: &[Vec<u8>],
    a: &gltf::Animation,
) -> Result<Animation> {
    use gltf::animation::util::ReadOutputs;
    let mut channels = Vec::new();
    for (ci, ch) in a.channels().enumerate() {
        let object = format!("animations[{}].channels[{ci}]", a.index());
        let sampler = ch.sampler();
        check_accessor(
            file,
            buffers,
            &sampler.input(),
            &format!("{object}.sampler.input"),
        )?;
        check_accessor(
            file,
            buffers,
            &sampler.output(),
            &format!("{object}.sampler.output"),
        )?;
        let reader = ch.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
        let times: Vec<f32> = reader
            .read_inputs()
            .ok_or_else(|| Error::scene(file, &object, "sampler input cannot be read"))?
            .collect();
        if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] <= w[0]) {
            return Err(Error::scene(
                file,
                &object,
                "key times must be finite and strictly increasing",
            ));
        }
        let (property, stride, values): (Property, usize, Vec<f32>) = match reader
            .read_outputs()
            .ok_or_else(|| Error::scene(file, &object, "sampler output cannot be read"))?
        {
            ReadOutputs::Translations(it) => (Property::Translation, 3, it.flatten().collect()),
            ReadOutputs::Scales(it) => (Property::Scale, 3, it.flatten().collect()),
            ReadOutputs::Rotations(it) => {
                (Property::Rotation, 4, it.into_f32().flatten().collect())
            }
            ReadOutputs::MorphTargetWeights(it) => {
                let v: Vec<f32> = it.into_f32().collect();
                (Property::Weights, 0, v)
            }
        };
        let interpolation = match sampler.interpolation() {
            gltf::animation::Interpolation::Step => Interpolation::Step,
            gltf::animation::Interpolation::Linear => Interpolation::Linear,
            gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
        };
        let per_key = if interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        let stride = if property == Property::Weights {
            values.len() / (times.len() * per_key).max(1)
        } else {
            stride
        };
        if stride == 0
            || values.len() != times.len() * per_key * stride
            || values.iter().any(|v| !v.is_finite())
        {
            return Err(Error::scene(
                file,
                &object,
                format!(
                    "sampler output holds {} values for {} keys: expected {per_key} x {stride} finite values per key",
                    values.len(),
                    times.len()
                ),
            ));
        }
        channels.push(Channel {
            node: ch.target().node().index(),
            property,
            interpolation,
            times,
            values,
            stride,
        });
    }
    Ok(Animation {
        name: a.name().map(str::to_owned),
        channels,
    })
}

impl Channel {
    fn element(&self, key: usize, part: usize) -> &[f32] {
        let per_key = if self.interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        let start = (key * per_key + part) * self.stride;
        &self.values[start..start + self.stride]
    }

    /// The value part of key `k` (for CUBICSPLINE, between the two tangents).
    fn value(&self, k: usize) -> &[f32] {
        self.element(
            k,
            if self.interpolation == Interpolation::CubicSpline {
                1
            } else {
                0
            },
        )
    }

    /// The channel's value at time `t`, clamped to the key range.
    pub fn sample(&self, t: f32) -> Vec<f32> {
        let n = self.times.len();
        if t <= self.times[0] || n == 1 {
            return self.finish(self.value(0).to_vec());
        }
        if t >= self.times[n - 1] {
            return self.finish(self.value(n - 1).to_vec());
        }
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let td = t1 - t0;
        let u = (t - t0) / td;
        let out = match self.interpolation {
            Interpolation::Step => self.value(k).to_vec(),
            Interpolation::Linear if self.property == Property::Rotation => {
                let a = quat(self.value(k));
                let mut b = quat(self.value(k + 1));
                if a.dot(b) < 0.0 {
                    b = -b;
                }
                a.slerp(b, u).to_array().to_vec()
            }
            Interpolation::Linear => self
                .value(k)
                .iter()
                .zip(self.value(k + 1))
                .map(|(a, b)| a + (b - a) * u)
                .collect(),
            Interpolation::CubicSpline => {
                // glTF 2.0 Appendix C: Hermite spline with tangents scaled by the key interval.
                let (u2, u3) = (u * u, u * u * u);
                let (h00, h10, h01, h11) = (
                    2.0 * u3 - 3.0 * u2 + 1.0,
                    u3 - 2.0 * u2 + u,
                    -2.0 * u3 + 3.0 * u2,
                    u3 - u2,
                );
                let (p0, m0) = (self.element(k, 1), self.element(k, 2));
                let (p1, m1) = (self.element(k + 1, 1), self.element(k + 1, 0));
                (0..self.stride)
                    .map(|i| h00 * p0[i] + h10 * td * m0[i] + h01 * p1[i] + h11 * td * m1[i])
                    .collect()
            }
        };
        self.finish(out)
    }

    /// Rotations leave normalized.
    fn finish(&self, mut v: Vec<f32>) -> Vec<f32> {
        if self.property == Property::Rotation {
            v = quat(&v).to_array().to_vec();
        }
        v
    }
}

fn quat(v: &[f32]) -> Quat {
    Quat::from_xyzw(v[0], v[1], v[2], v[3]).normalize()
}

/// Per-node animated state at one instant: overridden TRS parts and morph weights.
#[derive(Clone, Debug, Default)]
pub struct NodeOverrides {
    pub translation: Option<Vec3>,
    pub rotation: Option<Quat>,
    pub scale: Option<Vec3>,
    pub weights: Option<Vec<f32>>,
}

/// Pairs of animations (indices, earlier first) whose channels drive the same property of the
/// same node: played together (`animation = "all"`), the later overwrites the earlier there,
/// as a file's alternative clips (a walk, a run) do.
pub fn overlapping_animations(animations: &[Animation]) -> Vec<(usize, usize)> {
    let mut drivers: std::collections::BTreeMap<(usize, u8), Vec<usize>> = Default::default();
    for (a, anim) in animations.iter().enumerate() {
        for c in &anim.channels {
            let list = drivers.entry((c.node, c.property as u8)).or_default();
            if list.last() != Some(&a) {
                list.push(a);
            }
        }
    }
    let mut pairs: Vec<(usize, usize)> = drivers
        .values()
        .flat_map(|list| {
            list.iter()
                .enumerate()
                .flat_map(move |(k, &a)| list[k + 1..].iter().map(move |&b| (a, b)))
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// Samples the given animations at `t` into per-node overrides (later channels win).
pub fn sample(animations: &[&Animation], node_count: usize, t: f32) -> Vec<NodeOverrides> {
    let mut out = vec![NodeOverrides::default(); node_count];
    for a in animations {
        for c in &a.channels {
            let v = c.sample(t);
            let o = &mut out[c.node];
            match c.property {
                Property::Translation => o.translation = Some(Vec3::from_slice(&v)),
                Property::Scale => o.scale = Some(Vec3::from_slice(&v)),
                Property::Rotation => o.rotation = Some(quat(&v)),
                Property::Weights => o.weights = Some(v),
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(
        property: Property,
        interpolation: Interpolation,
        times: &[f32],
        values: &[f32],
        stride: usize,
    ) -> Channel {
        Channel {
            node: 0,
            property,
            interpolation,
            times: times.to_vec(),
            values: values.to_vec(),
            stride,
        }
    }

    #[test]
    fn step_and_linear_clamp_outside_their_keys() {
        let c = channel(
            Property::Translation,
            Interpolation::Linear,
            &[1.0, 3.0],
            &[0.0, 0.0, 0.0, 4.0, 2.0, -2.0],
            3,
        );
        assert_eq!(c.sample(0.0), vec![0.0, 0.0, 0.0]);
        assert_eq!(c.sample(2.0), vec![2.0, 1.0, -1.0]);
        assert_eq!(c.sample(9.0), vec![4.0, 2.0, -2.0]);
        let s = channel(
            Property::Scale,
            Interpolation::Step,
            &[0.0, 1.0],
            &[1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
            3,
        );
        assert_eq!(s.sample(0.99), vec![1.0, 1.0, 1.0]);
        assert_eq!(s.sample(1.0), vec![2.0, 2.0, 2.0]);
    }

    #[test]
    fn linear_rotation_takes_the_shortest_path() {
        // 0 and 270 degrees about Y; the second key stored with the "long way" sign.
        let a = Quat::IDENTITY;
        let b = -Quat::from_rotation_y(270f32.to_radians());
        let c = channel(
            Property::Rotation,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[a.x, a.y, a.z, a.w, b.x, b.y, b.z, b.w],
            4,
        );
        let mid = quat(&c.sample(0.5));
        // Shortest path from 0 to 270 degrees is -90: halfway is -45 degrees.
        let want = Quat::from_rotation_y(-45f32.to_radians());
        assert!(mid.dot(want).abs() > 0.9999, "{mid:?}");
    }

    #[test]
    fn cubic_spline_follows_the_hermite_formula_with_scaled_tangents() {
        // One float (a weight): keys at t = 0 (value 0, out-tangent 2) and t = 2 (value 1,
        // in-tangent 0). At u = 0.5: h00 0.5, h10 0.125, h01 0.5, h11 -0.125; td = 2.
        let values = [0.0, 0.0, 2.0, 0.0, 1.0, 0.0];
        let c = channel(
            Property::Weights,
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            &values,
            1,
        );
        let want = 0.5 * 0.0 + 0.125 * 2.0 * 2.0 + 0.5 * 1.0 + -0.125 * 2.0 * 0.0;
        assert!((c.sample(1.0)[0] - want).abs() < 1e-6);
        assert_eq!(c.sample(-1.0), vec![0.0]);
        assert_eq!(c.sample(5.0), vec![1.0]);
    }
}
