//! The selection of a collision field's closest candidates: a binary max-heap by distance
//! (the farthest at the root) that a closer candidate enters by replacing the root.

use nalgebra::RealField;

/// Puts `item` at node `root` of the binary max-heap `heap` (by distance, the farthest at the
/// root), whose subtrees below `root` are heaps, and restores the order of that subtree: the
/// larger child moves up into the hole until `item` is no closer than both children.
/// O(log len).
pub(super) fn sift<T: RealField + Copy>(heap: &mut [(T, usize)], root: usize, item: (T, usize)) {
    let mut hole = root;
    for _ in 0..heap.len() {
        let left = 2 * hole + 1;
        let Some(&l) = heap.get(left) else { break };
        let (child, c) = match heap.get(left + 1) {
            Some(&r) if r.0 > l.0 => (left + 1, r),
            _ => (left, l),
        };
        if c.0 <= item.0 {
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

/// Orders `heap` as a binary max-heap by distance (the farthest at the root), O(len).
pub(super) fn heapify<T: RealField + Copy>(heap: &mut [(T, usize)]) {
    for root in (0..heap.len() / 2).rev() {
        if let Some(&item) = heap.get(root) {
            sift(heap, root, item);
        }
    }
}
