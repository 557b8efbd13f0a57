//! The inner loops of [`super::TreeFactorization`]: the elimination update of `factorize` and
//! the ancestor-column combination of `inverse`, written for short trip counts.

use nalgebra::RealField;

/// The update of [`super::TreeFactorization::factorize`] after the elimination of one coordinate with
/// the scaled row `below = (L_{k,a})` over its ancestors `ancestors` (nearest first):
/// `H_{a_t, a_s} −= L_{k,a_t} L_{k,a_s}` for `s ≥ t`, i.e. packed row `a_t` minus
/// `L_{k,a_t} · below[t..]`. The ancestors are taken in pairs `(a_t, a_{t+1})`: both rows are
/// updated in one pass over `below[t+1..]`, each entry of `below` loaded once for two
/// multiply-adds.
#[inline(always)]
pub(super) fn eliminate<T: RealField + Copy, const N: usize>(rows: &mut [[T; N]], ancestors: &[u16], below: &[T]) {
    let mut t = 0;
    while let (Some(&[a0, a1]), Some(&[l0, l1])) = (
        ancestors.get(t..t + 2).and_then(|a| a.first_chunk::<2>()),
        below.get(t..t + 2).and_then(|b| b.first_chunk::<2>()),
    ) {
        let (a0, a1) = (usize::from(a0), usize::from(a1));
        let tail = below.get(t + 1..).unwrap_or(&[]);
        // `a1 < a0` (nearest ancestor first): row `a1` below the split, row `a0` its first row.
        if let Some((lower, upper)) = rows.split_at_mut_checked(a0) {
            if let (Some(row0), Some(row1)) = (upper.first_mut(), lower.get_mut(a1)) {
                if let (Some((first, rest0)), Some(rest1)) =
                    (row0.get_mut(..=tail.len()).and_then(|r| r.split_first_mut()), row1.get_mut(..tail.len()))
                {
                    *first -= l0 * l0;
                    for ((x0, x1), m) in rest0.iter_mut().zip(rest1.iter_mut()).zip(tail.iter()) {
                        let m = *m;
                        *x0 -= l0 * m;
                        *x1 -= l1 * m;
                    }
                }
            }
        }
        t += 2;
    }
    if let (Some(a), Some(tail)) = (ancestors.get(t), below.get(t..)) {
        if let (Some(target), Some(&l)) =
            (rows.get_mut(usize::from(*a)).and_then(|r| r.get_mut(..tail.len())), tail.first())
        {
            for (h, m) in target.iter_mut().zip(tail.iter()) {
                *h -= l * *m;
            }
        }
    }
}

/// `head_j = scale · Σ_a L_a w_a[j]` for `j < head.len()` over the ancestor columns
/// `w_a = columns[a]` and their weights `L_a = weights[·]` (paired in order): four entries of
/// `head` at a time in local accumulators, each ancestor column read once per block.
#[inline(always)]
pub(super) fn combine_ancestor_columns<T: RealField + Copy, const N: usize>(
    head: &mut [T],
    columns: &[[T; N]],
    ancestors: &[u16],
    weights: &[T],
    scale: T,
) {
    let mut blocks = head.chunks_exact_mut(4);
    let mut j = 0;
    for block in &mut blocks {
        let (mut s0, mut s1, mut s2, mut s3) = (T::zero(), T::zero(), T::zero(), T::zero());
        for (a, l) in ancestors.iter().zip(weights.iter()) {
            let entries = columns.get(usize::from(*a)).and_then(|w_a| w_a.get(j..)).and_then(|t| t.first_chunk::<4>());
            if let Some([y0, y1, y2, y3]) = entries {
                s0 += *l * *y0;
                s1 += *l * *y1;
                s2 += *l * *y2;
                s3 += *l * *y3;
            }
        }
        if let [x0, x1, x2, x3] = block {
            *x0 = s0 * scale;
            *x1 = s1 * scale;
            *x2 = s2 * scale;
            *x3 = s3 * scale;
        }
        j += 4;
    }
    for (offset, x) in blocks.into_remainder().iter_mut().enumerate() {
        let mut s = T::zero();
        for (a, l) in ancestors.iter().zip(weights.iter()) {
            s += *l * columns.get(usize::from(*a)).and_then(|w_a| w_a.get(j + offset)).copied().unwrap_or_else(T::zero);
        }
        *x = s * scale;
    }
}
