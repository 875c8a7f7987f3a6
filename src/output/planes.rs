//! Images as named channel planes: the form comparisons and difference images work in.

use super::image::Image;

/// A multi-channel image: channel planes, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Planes {
    pub width: usize,
    pub height: usize,
    pub names: Vec<String>,
    pub data: Vec<Vec<f32>>,
}

impl Planes {
    pub fn from_image(img: &Image) -> Planes {
        Planes {
            width: img.width,
            height: img.height,
            names: vec!["R".into(), "G".into(), "B".into()],
            data: (0..3).map(|c| img.channel(c)).collect(),
        }
    }

    /// The value of channel `c` at (x, y); 0 outside the image or its channels.
    pub fn value(&self, c: usize, x: usize, y: usize) -> f32 {
        if c < self.data.len() && x < self.width && y < self.height {
            self.data[c][y * self.width + x]
        } else {
            0.0
        }
    }
}
