//! The pools of spare reference vectors the binned build reuses, so that after the first few
//! levels it allocates nothing per node and rarely grows a vector into fresh pages: one per
//! thread for the nodes' lists, one shared for the chunks of the parallel partition; and the
//! gather of those chunks into one list.

use super::bins::Ref;
use rayon::prelude::*;
use std::cell::RefCell;

thread_local! {
    /// Spare reference vectors: a node returns its list once partitioned and its children take
    /// theirs from here, so after the first few levels the build allocates nothing per node.
    static SPARE: RefCell<Vec<Vec<Ref>>> = const { RefCell::new(Vec::new()) };
}

pub(super) fn take(capacity: usize) -> Vec<Ref> {
    let mut v = SPARE
        .with_borrow_mut(|s| {
            // The most recent spare that is large enough, among the last few: one that is too
            // small would be grown into fresh pages, and a first touch of a page costs a fault
            // (the 1M peer mesh's build faulted about 85k times, mostly here and in `partition`).
            // A large request looks through the whole pool (vectors of the previous build's top
            // levels lie deep in it, and a large fresh one costs a fault per page).
            let search = if capacity >= LARGE {
                s.len()
            } else {
                SPARE_SEARCH
            };
            let fits = s
                .iter()
                .rev()
                .take(search)
                .position(|v| v.capacity() >= capacity);
            match fits {
                Some(k) => Some(s.remove(s.len() - 1 - k)),
                None => s.pop(),
            }
        })
        .unwrap_or_default();
    v.clear();
    v.reserve(capacity);
    v
}

/// How many of the most recent spare vectors `take` looks through for one large enough.
const SPARE_SEARCH: usize = 8;
/// References from which `take` looks through every spare: 1.8 MB, where a node's work (tens of
/// microseconds) dwarfs looking through 256 capacities.
const LARGE: usize = 1 << 16;

pub(super) fn give(v: Vec<Ref>) {
    // Enough for both children of every node on a depth-first path, with room to spare.
    const KEEP: usize = 256;
    SPARE.with_borrow_mut(|s| {
        if s.len() < KEEP && v.capacity() > 0 {
            s.push(v)
        }
    });
}

/// The chunks' lists one after another in a spare vector, copied on all threads: the copy is
/// on the build's critical path at the top levels, where one node is all there is to do (about
/// 20-27 ms of one thread on the 1M peer mesh, copied serially).
pub(super) fn gather<'a>(chunks: impl Iterator<Item = &'a [Ref]> + Clone) -> Vec<Ref> {
    let n = chunks.clone().map(<[Ref]>::len).sum();
    let mut out = take(n);
    let mut rest = &mut out.spare_capacity_mut()[..n];
    let mut pieces = Vec::new();
    for c in chunks {
        let (piece, tail) = rest.split_at_mut(c.len());
        pieces.push((piece, c));
        rest = tail;
    }
    pieces
        .into_par_iter()
        .for_each(|(piece, c)| _ = piece.write_copy_of_slice(c));
    // SAFETY: the pieces above cover the first `n` slots, and each was written.
    unsafe { out.set_len(n) };
    out
}

/// Buffers of `CHUNK_CAPACITY` references for the parallel partition's chunks, shared by all
/// threads (a chunk is split on one thread and gathered on another). Each chunk of a large
/// node's list writes at most its own length to either side, so one of these always fits: the
/// thread-local pool above, looking through only its last few spares for requests of this
/// size, often grew a small spare into fresh pages instead (on the 1M peer mesh, about 120
/// fresh 458 KB buffers for the root alone, every build).
static CHUNK_SPARE: std::sync::Mutex<Vec<Vec<Ref>>> = std::sync::Mutex::new(Vec::new());

pub(super) const CHUNK_CAPACITY: usize = 1 << 14;

pub(super) fn take_chunk() -> Vec<Ref> {
    let spare = CHUNK_SPARE.lock().unwrap_or_else(|e| e.into_inner()).pop();
    let mut v = spare.unwrap_or_else(|| Vec::with_capacity(CHUNK_CAPACITY));
    v.clear();
    v
}

pub(super) fn give_chunk(v: Vec<Ref>) {
    // Both sides of every chunk of two large lists partitioned at once (the 1M peer mesh's
    // root has 62 chunks): at most 115 MB kept, and only by builds with lists that large.
    const KEEP: usize = 256;
    let mut spare = CHUNK_SPARE.lock().unwrap_or_else(|e| e.into_inner());
    if spare.len() < KEEP {
        spare.push(v);
    }
}
