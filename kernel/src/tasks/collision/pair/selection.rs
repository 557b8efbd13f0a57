//! The selection of a collision field's closest candidates: a binary max-heap by
//! `(distance, pair index)` (the farthest at the root, of equally far ones the later pair) that
//! a closer candidate enters by replacing the root. The order breaks ties by the pair index,
//! so the selection is the unique set of the smallest `(distance, pair index)`, which the
//! later fields of a cycle share (`PairRowCache`).

use nalgebra::RealField;

/// `a` after `b` in the order of the heap: farther, or as far and a later pair.
#[inline]
fn after<T: RealField + Copy>(a: (T, usize), b: (T, usize)) -> bool {
    a.0 > b.0 || (a.0 == b.0 && a.1 > b.1)
}

/// Puts `item` at node `root` of the binary max-heap `heap` (by `(distance, pair index)`, the
/// last at the root), whose subtrees below `root` are heaps, and restores the order of that
/// subtree: the later child moves up into the hole until `item` comes after both children.
/// O(log len).
pub(super) fn sift<T: RealField + Copy>(heap: &mut [(T, usize)], root: usize, item: (T, usize)) {
    let mut hole = root;
    for _ in 0..heap.len() {
        let left = 2 * hole + 1;
        let Some(&l) = heap.get(left) else { break };
        let (child, c) = match heap.get(left + 1) {
            Some(&r) if after(r, l) => (left + 1, r),
            _ => (left, l),
        };
        if !after(c, item) {
            break;
        }
        if let Some(h) = heap.get_mut(hole) {
            *h = c;
        }
        hole = child;
    }
    if let Some(h) = heap.get_mut(hole) {
        *h = item;
    }
}

/// Orders `heap` as a binary max-heap by `(distance, pair index)` (the last at the root), O(len).
pub(super) fn heapify<T: RealField + Copy>(heap: &mut [(T, usize)]) {
    for root in (0..heap.len() / 2).rev() {
        if let Some(&item) = heap.get(root) {
            sift(heap, root, item);
        }
    }
}
