//! Linear, scene-referred RGB images in f32: what the renderer produces and every output consumes.

use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    /// Row-major, top row first.
    pub pixels: Vec<Vec3>,
}

impl Image {
    pub fn new(width: usize, height: usize) -> Image {
        Image {
            width,
            height,
            pixels: vec![Vec3::ZERO; width * height],
        }
    }

    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Vec3 {
        self.pixels[y * self.width + x]
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: Vec3) {
        self.pixels[y * self.width + x] = v;
    }

    /// One channel as a flat plane (0 = R, 1 = G, 2 = B).
    pub fn channel(&self, c: usize) -> Vec<f32> {
        self.pixels.iter().map(|p| p[c]).collect()
    }

    pub fn from_channels(width: usize, height: usize, r: &[f32], g: &[f32], b: &[f32]) -> Image {
        Image {
            width,
            height,
            pixels: (0..width * height)
                .map(|i| Vec3::new(r[i], g[i], b[i]))
                .collect(),
        }
    }
}
