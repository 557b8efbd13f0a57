//! The wheeled mobile platform: its admittance interface and coupling compensation (Sec. 5.1)
//! and the singularity avoidance of its steerable wheels (Sec. 3.2).
//!
//! The platform of a wheeled humanoid is **velocity controlled**: a high-gain controller makes
//! the base follow a commanded velocity `ṙ_des` (`r = (x, y, θ)`, world frame) and compensates
//! every disturbance (Fig. 5.1). The whole-body impedance needs a force interface, so the
//! platform is given one:
//!
//! | file | thesis | what |
//! | --- | --- | --- |
//! | [`admittance`] | (5.1)–(5.5), (5.15) | virtual inertia and damping integrated into `ṙ_des`; velocity limits from force limits |
//! | [`coupling_compensation`] | (5.13)–(5.14) | `τ_comp = (0, M_qr r̈ + C_qr ṙ + g_q)`, switchable |
//! | [`storage`] | (5.16)–(5.22) | closed-loop inertia (5.17), storage function (5.21), its rate (5.22), a passivity monitor |
//! | [`icr`] | (3.25)–(3.36), Fig. 3.9 | ICR of the base twist, `J_sap` (3.28), repulsion from the nearest wheel, base accelerations at constant speed |
//! | [`legs`] | (3.37)–(3.40), Fig. 3.10 | nonlinear leg admittance, return-to-nominal gains |
//! | [`avoidance`] | Fig. 3.10 | the complete loop: reference + repulsion + return, integrated into `ṙ_des` and leg rates |
//!
//! The coordinates of the whole robot are `y = (r, q)` (5.7); [`PlatformLayout`] says where the
//! platform coordinates sit in the model's coordinate vector and which of them the admittance
//! drives.
//!
//! Every function here is allocation-free and panic-free; every division that can become
//! singular (`v → 0`, `θ̇ → 0`, `d_sap → 0`) is guarded and the guarded branch returns a defined
//! finite value. Bad inputs give a [`PlatformError`].

pub mod admittance;
pub mod avoidance;
pub mod coupling_compensation;
pub mod icr;
pub mod legs;
pub mod storage;

use core::fmt;

use nalgebra::RealField;

/// Number of wheeled legs of the platform (Sec. 3.2: four steerable wheels on legs of variable
/// length): the one constant of `hal`, which the sensor and actuator frames use too.
pub use hal::LEGS;

/// Why a platform algorithm refused its input or configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlatformError {
    /// A configuration value is out of its documented range (or NaN).
    InvalidParameter {
        /// The offending field.
        name: &'static str,
    },
    /// An input contains NaN or ±∞.
    NonFinite {
        /// The offending input.
        input: &'static str,
    },
    /// A coordinate index of a [`PlatformLayout`] is not below `N`, or two coincide.
    InvalidLayout,
}

impl fmt::Display for PlatformError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidParameter { name } => write!(f, "invalid platform parameter {name}"),
            Self::NonFinite { input } => write!(f, "non-finite platform input {input}"),
            Self::InvalidLayout => f.write_str("platform coordinates out of range or repeated"),
        }
    }
}

impl core::error::Error for PlatformError {}

/// How one platform axis `x`, `y` or `θ` appears in the robot's coordinates `y = (r, q)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlatformAxis {
    /// Driven by the admittance (5.1); the coordinate index in the model.
    Admitted(usize),
    /// Present in the model but held at rest by the velocity controller (`ṙ_i = 0`), e.g. the
    /// lateral and yaw axes in the experiments of Sec. 5.1.4, where "only the forward/backward
    /// motion of the platform is allowed" (footnote 2). It is not part of `y`.
    Locked(usize),
    /// The model has no such coordinate (e.g. the linear model of Fig. 5.2 has only `x`).
    Absent,
}

impl PlatformAxis {
    /// The coordinate index, if the axis is in the model.
    pub fn coordinate(&self) -> Option<usize> {
        match self {
            Self::Admitted(c) | Self::Locked(c) => Some(*c),
            Self::Absent => None,
        }
    }

    /// `true` if the admittance drives the axis.
    pub fn is_admitted(&self) -> bool {
        matches!(self, Self::Admitted(_))
    }
}

/// Where the platform coordinates `r = (x, y, θ)` sit among the `N` coordinates of a model, and
/// which of them the admittance drives. Every other coordinate is an upper-body coordinate `q`.
///
/// ```
/// use kernel::platform::{PlatformAxis, PlatformLayout};
/// // Justin-like model, forward/backward motion only (Sec. 5.1.4, footnote 2).
/// let layout = PlatformLayout::try_new::<20>([PlatformAxis::Admitted(0), PlatformAxis::Locked(1), PlatformAxis::Locked(2)]).unwrap();
/// assert!(layout.is_platform(1) && !layout.is_platform(3));
/// assert_eq!(layout.admitted_axes(), [true, false, false]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlatformLayout {
    axes: [PlatformAxis; 3],
}

impl PlatformLayout {
    /// Validates the axes `(x, y, θ)` for a model with `N` coordinates: indices below `N` and
    /// pairwise distinct. Errors: [`PlatformError::InvalidLayout`].
    pub fn try_new<const N: usize>(axes: [PlatformAxis; 3]) -> Result<Self, PlatformError> {
        let indices = axes.map(|a| a.coordinate());
        for (k, index) in indices.iter().enumerate() {
            let Some(c) = index else { continue };
            let repeated = indices.iter().skip(k + 1).any(|other| *other == Some(*c));
            if *c >= N || repeated {
                return Err(PlatformError::InvalidLayout);
            }
        }
        Ok(Self { axes })
    }

    /// The axes `(x, y, θ)`.
    pub fn axes(&self) -> [PlatformAxis; 3] {
        self.axes
    }

    /// Which of `(x, y, θ)` the admittance drives.
    pub fn admitted_axes(&self) -> [bool; 3] {
        self.axes.map(|a| a.is_admitted())
    }

    /// `true` if coordinate `coordinate` is a platform coordinate (admitted or locked).
    pub fn is_platform(&self, coordinate: usize) -> bool {
        self.axes.iter().any(|a| a.coordinate() == Some(coordinate))
    }
}

/// `x` clamped to `[−limit, limit]` for a `limit ≥ 0` (which may be `+∞`).
pub(crate) fn clamp_symmetric<T: RealField + Copy>(x: T, limit: T) -> T {
    x.max(-limit).min(limit)
}
