//! The torso workspace's twelve boundaries and the gains of their repulsive potentials.

use nalgebra::RealField;

use crate::tasks::TaskError;

/// Number of workspace boundaries (rows) of the torso.
pub const BOUNDARIES: usize = 12;

/// One boundary of the torso workspace.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Boundary {
    /// Arc 1 of Table A.1: `q_t2 = q_t2,min` (−90°); centre `(−l_t2, 0)`, radius `l_t3`.
    Joint2Min,
    /// Arc 2: `q_t3 = q_t3,max` (135°); centre 0, radius `√(l_t2² + l_t3² − √2 l_t2 l_t3)`.
    Joint3Max,
    /// Arc 3: `q_t2 + q_t3 = max` (135°); centre `(l_t3/√2, −l_t3/√2)`, radius `l_t2`.
    SumMax,
    /// Arc 4: `q_t2 = q_t2,max` (90°); centre `(l_t2, 0)`, radius `l_t3`.
    Joint2Max,
    /// Arc 5: `q_t3 = q_t3,min` (0°, outstretched); centre 0, radius `l_t2 + l_t3`.
    Joint3Min,
    /// Arc 6: `q_t2 + q_t3 = min` (0°); centre `(0, l_t3)`, radius `l_t2`.
    SumMin,
    /// Line `τ_t2 = τ_t2,min` (3.48).
    Torque2Min,
    /// Line `τ_t2 = τ_t2,max` (3.48).
    Torque2Max,
    /// Circle `τ_t3,min`, `+` sign of (3.49) (Table A.2 row 1: feasible inside).
    Torque3MinPlus,
    /// Circle `τ_t3,min`, `−` sign (Table A.2 row 2: feasible outside).
    Torque3MinMinus,
    /// Circle `τ_t3,max`, `+` sign (Table A.2 row 3: feasible outside).
    Torque3MaxPlus,
    /// Circle `τ_t3,max`, `−` sign (Table A.2 row 4: feasible inside).
    Torque3MaxMinus,
}

impl Boundary {
    /// All boundaries in row order.
    pub const ALL: [Self; BOUNDARIES] = [
        Self::Joint2Min,
        Self::Joint3Max,
        Self::SumMax,
        Self::Joint2Max,
        Self::Joint3Min,
        Self::SumMin,
        Self::Torque2Min,
        Self::Torque2Max,
        Self::Torque3MinPlus,
        Self::Torque3MinMinus,
        Self::Torque3MaxPlus,
        Self::Torque3MaxMinus,
    ];

    /// Position in [`Boundary::ALL`] (the row index).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The arc number of Table A.1 / Fig. 3.15b for a kinematic boundary.
    pub const fn table_a1_arc(self) -> Option<u8> {
        match self {
            Self::Joint2Min => Some(1),
            Self::Joint3Max => Some(2),
            Self::SumMax => Some(3),
            Self::Joint2Max => Some(4),
            Self::Joint3Min => Some(5),
            Self::SumMin => Some(6),
            _ => None,
        }
    }

    /// `true` for the six kinematic boundaries, `false` for the load-dependent ones.
    pub const fn is_kinematic(self) -> bool {
        self.table_a1_arc().is_some()
    }

    /// Short snake-case name (for logs and plots), e.g. `"joint2_min"`, `"torque3_min_plus"`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Joint2Min => "joint2_min",
            Self::Joint3Max => "joint3_max",
            Self::SumMax => "sum_max",
            Self::Joint2Max => "joint2_max",
            Self::Joint3Min => "joint3_min",
            Self::SumMin => "sum_min",
            Self::Torque2Min => "torque2_min",
            Self::Torque2Max => "torque2_max",
            Self::Torque3MinPlus => "torque3_min_plus",
            Self::Torque3MinMinus => "torque3_min_minus",
            Self::Torque3MaxPlus => "torque3_max_plus",
            Self::Torque3MaxMinus => "torque3_max_minus",
        }
    }
}

/// Gains of the repulsive potential (3.8) and of its damping and activation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RepulsionGains<T> {
    /// Activation distance `d₀ > 0` (m): the potential is zero beyond it.
    pub distance: T,
    /// Force `F_max ≥ 0` (N) at the boundary (`d = 0`); the largest stiffness is `2 F_max/d₀`.
    pub max_force: T,
    /// Damping ratio `ξ ≥ 0` of each row (Sec. 3.1.3).
    pub damping_ratio: T,
    /// Distance (m) at and below which the activation is 1 (`ϑ₁` of (4.68)).
    pub activation_full: T,
    /// Distance (m) from which on the activation is 0 (`ϑ₂` of (4.68)), `> activation_full`.
    pub activation_start: T,
}

impl<T: RealField + Copy> RepulsionGains<T> {
    /// Gains from the largest stiffness `k_max = 2 F_max/d₀` (N/m) at the boundary; activation
    /// from 0 at `d₀` to 1 at the boundary.
    pub fn from_max_stiffness(max_stiffness: T, distance: T, damping_ratio: T) -> Self {
        let half: T = nalgebra::convert(0.5);
        Self {
            distance,
            max_force: half * max_stiffness * distance,
            damping_ratio,
            activation_full: T::zero(),
            activation_start: distance,
        }
    }

    /// The torso experiment of Sec. 3.3.5: largest stiffness 1000 N/m, `d₀ = 0.1 m`
    /// (so `F_max = 50 N`), `ξ = 0.3`.
    pub fn thesis_experiment() -> Self {
        Self::from_max_stiffness(nalgebra::convert(1000.0), nalgebra::convert(0.1), nalgebra::convert(0.3))
    }

    /// Potential `V(d)` (J) of (3.8): `F_max/(3 d₀²) (d₀ − d)³` for `d < d₀`, else 0.
    #[inline]
    pub fn potential(&self, d: T) -> T {
        let gap = (self.distance - d).max(T::zero());
        let three: T = nalgebra::convert(3.0);
        self.max_force / (three * self.distance * self.distance) * gap * gap * gap
    }

    /// Repulsive force `−∂V/∂d = F_max/d₀² (d₀ − d)²` (N) for `d < d₀`, else 0 (3.10).
    #[inline]
    pub fn force(&self, d: T) -> T {
        let gap = (self.distance - d).max(T::zero());
        self.max_force / (self.distance * self.distance) * gap * gap
    }

    /// Local stiffness `∂²V/∂d² = 2 F_max (d₀ − d)/d₀²` (N/m) for `d < d₀`, else 0.
    #[inline]
    pub fn stiffness(&self, d: T) -> T {
        let gap = (self.distance - d).max(T::zero());
        let two: T = nalgebra::convert(2.0);
        two * self.max_force / (self.distance * self.distance) * gap
    }

    /// Finite `d₀ > 0`, `F_max ≥ 0`, `ξ ≥ 0`, `activation_full < activation_start`.
    pub fn validate(&self) -> Result<(), TaskError> {
        let finite = |x: T| x.is_finite();
        if !(finite(self.distance) && self.distance > T::zero()) {
            return Err(TaskError::InvalidParameter { name: "distance" });
        }
        if !(finite(self.max_force) && self.max_force >= T::zero()) {
            return Err(TaskError::InvalidParameter { name: "max_force" });
        }
        if !(finite(self.damping_ratio) && self.damping_ratio >= T::zero()) {
            return Err(TaskError::InvalidParameter { name: "damping_ratio" });
        }
        if !(finite(self.activation_full)
            && finite(self.activation_start)
            && self.activation_full < self.activation_start)
        {
            return Err(TaskError::InvalidParameter { name: "activation" });
        }
        Ok(())
    }
}
