//! The per-thread pool of spare reference vectors the binned build reuses, so that after the
//! first few levels it allocates nothing per node and rarely grows a vector into fresh pages.

use super::bins::Ref;
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
