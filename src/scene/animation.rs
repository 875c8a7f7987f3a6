//! What a glTF file animates, summarised per kind (TRS channels, morph weights, skins). The samplers
//! themselves are evaluated by the animation stage; `info` and `check` use this summary.

use serde::Serialize;

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

pub(super) fn summarize(animation: &gltf::Animation) -> AnimationSummary {
    use gltf::animation::Property;
    let mut s = AnimationSummary {
        name: animation.name().map(str::to_owned),
        ..Default::default()
    };
    for channel in animation.channels() {
        match channel.target().property() {
            Property::Translation => s.translation_channels += 1,
            Property::Rotation => s.rotation_channels += 1,
            Property::Scale => s.scale_channels += 1,
            Property::MorphTargetWeights => s.weight_channels += 1,
        }
        let interp = format!("{:?}", channel.sampler().interpolation()).to_uppercase();
        if !s.interpolations.contains(&interp) {
            s.interpolations.push(interp);
        }
        if let Some(max) = channel.sampler().input().max()
            && let Some(t) = max
                .as_array()
                .and_then(|a| a.first())
                .and_then(|v| v.as_f64())
        {
            s.duration = s.duration.max(t as f32);
        }
    }
    s
}
