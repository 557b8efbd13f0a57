//! The inverse reflected mass (3.20) of one point-Jacobian row over the tree factor, with the
//! row's last coordinate given by the caller (the pair Jacobian walks know it).

use nalgebra::RealField;

use super::TreeFactorization;

impl<T: RealField + Copy, const N: usize> TreeFactorization<T, N> {
    /// `J M⁻¹ Jᵀ = ‖J L⁻¹‖²` (3.20) for the row `J = (head, 0, …, 0)`, whose leaf (the last
    /// coordinate of its support) is taken to be `head.len() − 1` instead of searched: the
    /// substitution of [`Self::inverse_reflected_mass`] along that coordinate's ancestor chain,
    /// with the same operations in the same order (the same bits as
    /// [`Self::inverse_reflected_masses`]). When the chain's coordinates are consecutive (one
    /// limb of a serial chain, e.g. an arm that follows the torso in the coordinate order) the
    /// chain's entries are `head`'s last entries reversed and no entry can lie between them;
    /// otherwise the entries between chain coordinates are checked to be zero. Roots below the
    /// chain are solved alone; a row with any other support (or a `head` longer than `N`) is
    /// passed to [`Self::inverse_reflected_masses`]. A zero last entry costs one more chain
    /// entry and changes nothing. Cost: depth²/2 multiply-adds and one pass over `head`.
    pub fn inverse_reflected_mass_of_head(&self, head: &[T]) -> T {
        match self.substitute_head(head, &mut [T::zero(); N], |_, _| {}) {
            Some(norm) => norm,
            None => self.inverse_reflected_mass_fallback(head),
        }
    }

    /// The chain substitution of [`Self::inverse_reflected_mass_of_head`] with its solution:
    /// returns `‖x‖²`, `x = J L⁻¹` (the inverse reflected mass (3.20), the same bits), and
    /// passes each entry of `x` that the substitution forms to `solution(coordinate, value)`
    /// (the chain's coordinates and the roots below it with a nonzero entry; the other entries
    /// of `x` are zero). `x` is linear in the row, so for two rows `J₁`, `J₂` with solutions
    /// `x₁`, `x₂`, `(J₂ − J₁) M⁻¹ (J₂ − J₁)ᵀ = ‖x₂ − x₁‖²`. `None` (and `solution` possibly
    /// called for some entries) when the row's support is not that chain and those roots:
    /// [`Self::inverse_reflected_mass_of_head`] then takes the general path. `work` is the
    /// substitution's buffer (its content on entry does not matter: one buffer serves several
    /// calls).
    #[inline(always)]
    pub fn substitute_head(&self, head: &[T], work: &mut [T; N], mut solution: impl FnMut(usize, T)) -> Option<T> {
        let Some(leaf) = head.len().checked_sub(1) else {
            return Some(T::zero());
        };
        let (Some(depth), Some(chain)) = (self.structure.depth.get(leaf), self.structure.chains.get(leaf)) else {
            return None;
        };
        let chain = chain.get(..=usize::from(*depth)).unwrap_or(&[]);
        let root = chain.last().map_or(0, |r| usize::from(*r));
        let packed = work.get_mut(..chain.len()).unwrap_or(&mut []);
        let mut other = false;
        if root + chain.len() == head.len() {
            // The chain is `leaf, leaf − 1, …, root`.
            for (y, x) in packed.iter_mut().zip(head.get(root..).unwrap_or(&[]).iter().rev()) {
                *y = *x;
            }
        } else {
            let mut above = head.len();
            for (y, a) in packed.iter_mut().zip(chain.iter()) {
                let a = usize::from(*a);
                *y = match head.get(a..above).and_then(|s| s.split_first()) {
                    Some((value, gap)) => {
                        other |= gap.iter().any(|x| !x.is_zero());
                        *value
                    }
                    None => T::zero(),
                };
                above = a;
            }
        }
        let mut norm = T::zero();
        let mut tail = packed;
        for k in chain {
            let Some((y, ancestors)) = tail.split_first_mut() else { break };
            let k = usize::from(*k);
            let (Some(l), Some(inverse)) = (self.rows.data.0.get(k), self.reciprocal.get(k)) else { break };
            let x = *y * *inverse;
            norm += x * x;
            solution(k, x);
            // The chain of `k` is the rest of the leaf's chain: its packed row pairs entry by
            // entry (two exits instead of `zip`: the loops are short).
            let mut l = l.get(1..).unwrap_or(&[]).iter();
            for t in ancestors.iter_mut() {
                let Some(l_ka) = l.next() else { break };
                *t -= *l_ka * x;
            }
            tail = ancestors;
        }
        // Below the chain's root: roots are solved alone (from the last coordinate down).
        if let (Some(x), Some(d), Some(r)) =
            (head.get(..root), self.structure.depth.get(..root), self.reciprocal.get(..root))
        {
            for (k, ((x, d), inverse)) in x.iter().zip(d).zip(r).enumerate().rev() {
                if !x.is_zero() {
                    other |= *d != 0;
                    let y = *x * *inverse;
                    norm += y * y;
                    solution(k, y);
                }
            }
        }
        (!other).then_some(norm)
    }

    /// [`Self::inverse_reflected_masses`] of `(head, 0, …, 0)` (the entries of `head` beyond
    /// `N` ignored).
    fn inverse_reflected_mass_fallback(&self, head: &[T]) -> T {
        let mut row = [T::zero(); N];
        for (x, h) in row.iter_mut().zip(head) {
            *x = *h;
        }
        let [w] = self.inverse_reflected_masses([&row]);
        w
    }
}
