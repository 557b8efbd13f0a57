//! The posture whose TCP comes nearest to a target: the one search behind the generic
//! scenarios' reachability figures (`limits`' nearest reachable point, `self_collision`'s goals).
//!
//! Active-set damped least squares on the TCP's pose error `e = (p* − p, W log(R* Rᵀ))` with the
//! frame's world-aligned Jacobian (`W` the orientation weight in m/rad; without a target
//! orientation the position alone), over the coordinates that move, within their ranges narrowed
//! by a margin at both ends: a coordinate at a bound whose step points outward is taken out of
//! the step; a step is halved until `|e|` does not grow and the manipulability bound, if any,
//! holds (at most [`HALVINGS`] times); the search ends when a step moves the
//! posture less than `1e-10` or after [`ITERATIONS`]. The search is local: the result depends
//! on the seed.

use kernel::dynamics::{forward_kinematics, frame_jacobian};
use kernel::model::{Data, FrameId, Model, Placement};
use kernel::tasks::cartesian_impedance::AxisMask;
use kernel::tasks::manipulability::manipulability;
use nalgebra::{Matrix6, Rotation3, SMatrix, SVector, Vector3, Vector6};

/// Damping `λ` of the least squares (m).
pub const DAMPING: f64 = 0.02;
/// Iterations at most.
pub const ITERATIONS: usize = 2000;
/// Halvings of a step at most.
pub const HALVINGS: usize = 30;

/// A posture the search reached: the coordinates and the TCP's placement there.
pub type Reached<const N: usize> = (SVector<f64, N>, Placement<f64>);

/// The TCP's placement and its weighted pose error `e`.
type Evaluated = (Placement<f64>, Vector6<f64>);

/// What the search keeps and what it looks for.
pub struct NearestPosture<'a, const N: usize, const B: usize, const F: usize> {
    /// The plant model: its kinematics and its ranges.
    pub model: &'a Model<f64, N, B, F>,
    /// The TCP frame.
    pub tcp: FrameId,
    /// The coordinates that move; the others keep the seed's values.
    pub moves: [bool; N],
    /// How far inside each finite bound the moving coordinates stay (the end stops' margin: no
    /// stop acts there; 0: the ranges).
    pub margin: f64,
    /// The target orientation and its weight `W` (m/rad), if the orientation counts.
    pub orientation: Option<(Rotation3<f64>, f64)>,
    /// The manipulability bound `m ≥ m₀` of the TCP's rows over the arm's coordinates, if any.
    pub manipulability: Option<(AxisMask, [bool; N], f64)>,
}

impl<const N: usize, const B: usize, const F: usize> NearestPosture<'_, N, B, F> {
    /// The posture nearest to `target` from `seed` (its moving coordinates clamped into the
    /// narrowed ranges) and the TCP's placement there; `None` if the seed is below the
    /// manipulability bound.
    pub fn search(&self, seed: &SVector<f64, N>, target: &Vector3<f64>) -> Result<Option<Reached<N>>, String> {
        let narrowed = |bound: f64, inward: f64| if bound.is_finite() { bound + inward } else { bound };
        let lower = self.model.limits.position_lower.map(|l| narrowed(l, self.margin));
        let upper = self.model.limits.position_upper.map(|u| narrowed(u, -self.margin));
        let moves = SVector::<bool, N>::from(self.moves);
        let clamp = |q: SVector<f64, N>| {
            SVector::<f64, N>::from_fn(|k, _| match (q.get(k), lower.get(k), upper.get(k), moves.get(k)) {
                (Some(x), Some(l), Some(u), Some(true)) => x.clamp(*l, *u),
                (Some(x), ..) => *x,
                _ => f64::NAN,
            })
        };
        let mut data = Data::new(self.model);
        let mut q = clamp(*seed);
        let (mut placement, mut error) = match self.evaluate(&mut data, &q, target)? {
            Some(evaluated) => evaluated,
            None => return Ok(None),
        };
        let weight = self.orientation.map_or(0.0, |(_, w)| w);
        let mut jacobian = SMatrix::<f64, 6, N>::zeros();
        // `data` holds the kinematics of `q`: the last posture `evaluate` saw is the accepted one.
        for _ in 0..ITERATIONS {
            frame_jacobian(self.model, &data, self.tcp, &mut jacobian).map_err(|e| e.to_string())?;
            jacobian.fixed_rows_mut::<3>(3).scale_mut(weight);
            let mut free = self.moves;
            let mut step = SVector::<f64, N>::zeros();
            for _ in 0..=N {
                let mut j = jacobian;
                for (k, moving) in free.iter().enumerate() {
                    if !moving {
                        j.column_mut(k).fill(0.0);
                    }
                }
                let gram = j * j.transpose() + Matrix6::identity() * DAMPING * DAMPING;
                step = j.transpose() * gram.try_inverse().ok_or("singular Gram matrix")? * error;
                let mut blocked = false;
                let bounds = lower.iter().zip(upper.iter());
                for (((moving, x), dx), (l, u)) in free.iter_mut().zip(q.iter()).zip(step.iter()).zip(bounds) {
                    if *moving && ((x <= l && *dx < 0.0) || (x >= u && *dx > 0.0)) {
                        (*moving, blocked) = (false, true);
                    }
                }
                if !blocked {
                    break;
                }
            }
            let mut scale = 1.0;
            let mut accepted = None;
            for _ in 0..HALVINGS {
                let candidate = clamp(q + step * scale);
                if let Some((p, e)) = self.evaluate(&mut data, &candidate, target)? {
                    if e.norm() <= error.norm() {
                        accepted = Some((candidate, p, e));
                        break;
                    }
                }
                scale *= 0.5;
            }
            let Some((next, next_placement, next_error)) = accepted else { break };
            let moved = (next - q).norm();
            (q, placement, error) = (next, next_placement, next_error);
            if moved < 1e-10 {
                break;
            }
        }
        Ok(Some((q, placement)))
    }

    /// The TCP's placement at `q` and its weighted pose error to `target`; `None` below the
    /// manipulability bound.
    fn evaluate(
        &self,
        data: &mut Data<f64, N, B, F>,
        q: &SVector<f64, N>,
        target: &Vector3<f64>,
    ) -> Result<Option<Evaluated>, String> {
        forward_kinematics(self.model, data, q, &SVector::zeros()).map_err(|e| e.to_string())?;
        if let Some((rows, arm, bound)) = &self.manipulability {
            let m = manipulability(self.model, data, self.tcp, *rows, arm).map_err(|e| e.to_string())?.value;
            if m < *bound {
                return Ok(None);
            }
        }
        let placement = *data.frame_placements.get(self.tcp.0).ok_or("no TCP frame")?;
        let position = target - placement.translation.vector;
        let turn = self.orientation.map_or_else(Vector3::zeros, |(rotation, weight)| {
            (rotation * placement.rotation.inverse()).scaled_axis() * weight
        });
        Ok(Some((placement, Vector6::new(position.x, position.y, position.z, turn.x, turn.y, turn.z))))
    }
}
