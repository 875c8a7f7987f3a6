//! An array on the GPU that a shader reads as one but that may sit in two storage buffers: when
//! it is larger than the adapter binds in one, the second holds the rest and the shader reads on
//! past the first's end (`node_at`, `prim_at`, `tri_at`, `box_at` in the WGSL). Written in place,
//! so that a frame writes only the elements that changed.

use super::buffers::checked;
use super::device::Gpu;
use crate::error::{Error, Result};
use bytemuck::Pod;

pub struct SplitArray {
    pub(super) first: wgpu::Buffer,
    /// The elements past `split`; a one-element placeholder the shader never reads when the
    /// array fits one buffer.
    pub(super) rest: wgpu::Buffer,
    split: usize,
    capacity: usize,
    element: usize,
}

/// Elements in the first buffer of an array of `capacity` elements of `element` bytes, in
/// buffers of at most `limit` bytes (0: split at the middle); an error naming `what` and
/// `adapter` when the array needs more than two.
fn first_part(
    what: &str,
    element: usize,
    capacity: usize,
    limit: u64,
    adapter: &str,
) -> Result<usize> {
    let bytes = (capacity * element) as u64;
    if limit == 0 {
        return Ok(capacity.div_ceil(2));
    }
    let first = ((limit / element as u64) as usize).min(capacity);
    if capacity - first > first {
        return Err(Error::Device {
            message: format!(
                "{what} need {:.1} MiB, more than twice the {:.1} MiB {adapter} binds in one \
                 buffer; render this scene with the CPU backend",
                bytes as f64 / 1048576.0,
                limit as f64 / 1048576.0,
            ),
        });
    }
    Ok(first)
}

impl SplitArray {
    /// Room for `capacity` zeroed elements of `element` bytes, in buffers of at most `limit`
    /// bytes each (`limit` 0: split at the middle whatever the size, the path of an array over
    /// the limit, for tests). More than twice the limit is refused, naming `what`.
    pub fn new(
        gpu: &Gpu,
        what: &str,
        element: usize,
        capacity: usize,
        limit: u64,
    ) -> Result<SplitArray> {
        let split = first_part(what, element, capacity, limit, &gpu.info.name)?;
        // A binding may not be empty: an unused part holds one element.
        let buffer = |elements: usize| {
            checked(gpu, what, || {
                gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(what),
                    size: (elements.max(1) * element) as u64,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
        };
        Ok(SplitArray {
            first: buffer(split)?,
            rest: buffer(capacity - split)?,
            split,
            capacity,
            element,
        })
    }

    /// `items` in a new array (see `new`).
    pub fn filled<T: Pod>(gpu: &Gpu, what: &str, items: &[T], limit: u64) -> Result<SplitArray> {
        let array = Self::new(gpu, what, std::mem::size_of::<T>(), items.len(), limit)?;
        array.write(gpu, 0, items);
        Ok(array)
    }

    /// Writes `items` from element `at` on; the bytes written.
    pub fn write<T: Pod>(&self, gpu: &Gpu, at: usize, items: &[T]) -> u64 {
        assert_eq!(std::mem::size_of::<T>(), self.element, "one element type");
        assert!(
            at + items.len() <= self.capacity,
            "written within the array"
        );
        let (before, after) = items.split_at(self.split.saturating_sub(at).min(items.len()));
        if !before.is_empty() {
            let offset = (at * self.element) as u64;
            gpu.queue
                .write_buffer(&self.first, offset, bytemuck::cast_slice(before));
        }
        if !after.is_empty() {
            let offset = ((at + before.len() - self.split) * self.element) as u64;
            gpu.queue
                .write_buffer(&self.rest, offset, bytemuck::cast_slice(after));
        }
        (items.len() * self.element) as u64
    }

    /// Bytes the array holds on the GPU.
    pub fn size(&self) -> u64 {
        self.first.size() + self.rest.size()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_array_fills_the_first_buffer_then_the_second_and_no_third() {
        const MIB: u64 = 1 << 20;
        let part = |capacity| first_part("the nodes", 8, capacity, MIB, "Card");
        assert_eq!(part(1000).unwrap(), 1000);
        assert_eq!(part(MIB as usize / 8).unwrap(), MIB as usize / 8);
        assert_eq!(part(MIB as usize / 4).unwrap(), MIB as usize / 8);
        let e = part(MIB as usize / 4 + 1).unwrap_err().to_string();
        assert!(
            e.contains("the nodes need 2.0 MiB")
                && e.contains("twice the 1.0 MiB Card binds")
                && e.contains("CPU backend"),
            "{e}"
        );
        // An element that does not divide the limit: the parts hold whole elements.
        assert!(first_part("t", 36, 50, 100, "Card").is_err());
        assert_eq!(first_part("t", 36, 4, 100, "Card").unwrap(), 2);
        assert_eq!(first_part("t", 36, 5, 0, "Card").unwrap(), 3);
    }
}
