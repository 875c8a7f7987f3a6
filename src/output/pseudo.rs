//! Delayed-channel pseudo-stereo (the Pulfrich-style method of pseudo-stereo TV): output frame n
//! takes the "now" channels from frame n and the other channels from frame n - delay. The first
//! `delay` frames have no frame that old; they take the delayed channels from the earliest frame
//! of the sequence, so the sequence starts flat and gains depth once the delay is filled.
//!
//! It works on the 8-bit display frames: the display transform maps each channel on its own, so
//! taking channels before or after it gives the same bytes, and a render farm can store the
//! frames losslessly as PNG and composite them in its last step.

use serde::Deserialize;
use std::collections::VecDeque;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Channels {
    #[default]
    Red,
    Green,
    Blue,
    /// Red and green now, blue delayed.
    RedGreen,
    /// Green and blue now, red delayed.
    GreenBlue,
    /// Red and blue now, green delayed.
    RedBlue,
}

impl Channels {
    fn mask(self) -> [bool; 3] {
        match self {
            Channels::Red => [true, false, false],
            Channels::Green => [false, true, false],
            Channels::Blue => [false, false, true],
            Channels::RedGreen => [true, true, false],
            Channels::GreenBlue => [false, true, true],
            Channels::RedBlue => [true, false, true],
        }
    }
}

pub struct PseudoStereo {
    now: [bool; 3],
    delay: usize,
    /// The last `delay + 1` frames (RGB, 8 bits per channel), newest last.
    history: VecDeque<Vec<u8>>,
}

impl PseudoStereo {
    pub fn new(channels_now: Channels, delay: usize) -> PseudoStereo {
        PseudoStereo {
            now: channels_now.mask(),
            delay,
            history: VecDeque::with_capacity(delay + 1),
        }
    }

    /// Takes the next frame of the sequence and returns the composited output frame.
    pub fn push(&mut self, frame: Vec<u8>) -> Vec<u8> {
        if self.history.len() == self.delay + 1 {
            self.history.pop_front();
        }
        self.history.push_back(frame);
        let current = self.history.back().expect("a frame was just pushed");
        // Oldest kept frame: n - delay, or the first frame while fewer are available.
        let delayed = self.history.front().expect("history is not empty");
        let mut out = current.clone();
        for (o, d) in out.chunks_exact_mut(3).zip(delayed.chunks_exact(3)) {
            for c in 0..3 {
                if !self.now[c] {
                    o[c] = d[c];
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn numbered(n: u8) -> Vec<u8> {
        vec![n; 3]
    }

    #[test]
    fn red_now_green_and_blue_from_two_frames_ago_starting_from_the_first() {
        let mut p = PseudoStereo::new(Channels::Red, 2);
        let out: Vec<Vec<u8>> = (0..5).map(|n| p.push(numbered(n))).collect();
        assert_eq!(out[0], [0, 0, 0]);
        assert_eq!(out[1], [1, 0, 0]);
        assert_eq!(out[2], [2, 0, 0]);
        assert_eq!(out[3], [3, 1, 1]);
        assert_eq!(out[4], [4, 2, 2]);
    }

    #[test]
    fn zero_delay_is_the_plain_sequence() {
        let mut p = PseudoStereo::new(Channels::GreenBlue, 0);
        assert_eq!(p.push(numbered(3)), [3, 3, 3]);
    }
}
