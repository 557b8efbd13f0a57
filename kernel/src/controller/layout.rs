//! Which frames and coordinates belong to which part of the robot: the arms ([`ArmId`], `A` of
//! them, each with its TCP), the joint groups and the [`RobotLayout`] that maps them to
//! coordinates and TCP frames. A robot has an optional platform (every [`PlatformAxis`] absent:
//! none), an optional torso and one or more arms.
//!
//! [`PlatformAxis`]: crate::platform::PlatformAxis

use heapless::Vec;

use crate::model::FrameId;
use crate::platform::PlatformLayout;

/// Most arms a layout may have.
pub const MAX_ARMS: usize = 4;

/// Most joint groups of a layout: platform, torso, upper body and one per arm.
pub const MAX_GROUPS: usize = 3 + MAX_ARMS;

/// One entry per arm, indexed by [`ArmId`] ([`ArmId::of`], [`ArmId::of_mut`], [`ArmId::index`]).
pub type PerArm<X, const A: usize> = [X; A];

/// One arm (its TCP and its coordinates): the arm's position in [`PerArm`] arrays. On the wire it
/// is one byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub struct ArmId(pub u8);

impl ArmId {
    /// Justin's right arm, the first.
    pub const RIGHT: ArmId = ArmId(0);
    /// Justin's left arm, the second.
    pub const LEFT: ArmId = ArmId(1);

    /// Every arm of a robot with `A` arms, in [`PerArm`] order.
    pub fn all<const A: usize>() -> [ArmId; A] {
        core::array::from_fn(|i| ArmId(u8::try_from(i).unwrap_or(u8::MAX)))
    }

    /// The arm's position in a [`PerArm`] array.
    pub const fn index(self) -> usize {
        self.0 as usize
    }

    /// This arm's entry of `per_arm`, `None` for an arm the robot does not have.
    pub fn of<X, const A: usize>(self, per_arm: &PerArm<X, A>) -> Option<&X> {
        per_arm.get(self.index())
    }

    /// This arm's entry of `per_arm`, mutable; `None` for an arm the robot does not have.
    pub fn of_mut<X, const A: usize>(self, per_arm: &mut PerArm<X, A>) -> Option<&mut X> {
        per_arm.get_mut(self.index())
    }

    /// A short name for task names: `right` and `left` for the first two arms (Justin's),
    /// `arm_2` and `arm_3` for the others.
    pub const fn name(self) -> &'static str {
        match self.0 {
            0 => "right",
            1 => "left",
            2 => "arm_2",
            3 => "arm_3",
            _ => "unknown_arm",
        }
    }
}

/// A group of coordinates a joint-space task acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum JointGroup {
    /// The admitted platform coordinates `(x, y, θ)`.
    Platform,
    /// The torso.
    Torso,
    /// One arm.
    Arm(ArmId),
    /// Every coordinate that is not the platform's: torso and arms.
    UpperBody,
}

/// The first `C` items in a fixed-capacity list. heapless' `collect` panics when the items do
/// not fit, and the controller's setup path is linked without a panic handler
/// (`firmware/wcet/panic_check.sh`); the lists built here fit by construction.
pub(crate) fn collect_truncated<X, const C: usize>(items: impl IntoIterator<Item = X>) -> Vec<X, C> {
    let mut list = Vec::new();
    for item in items {
        if list.push(item).is_err() {
            break;
        }
    }
    list
}

impl JointGroup {
    /// Every group of a robot with `A` arms, whether it has coordinates or not:
    /// platform, torso, the arms, upper body.
    pub fn all<const A: usize>() -> Vec<JointGroup, MAX_GROUPS> {
        let arms = ArmId::all::<A>().into_iter().take(MAX_ARMS).map(JointGroup::Arm);
        collect_truncated(
            [JointGroup::Platform, JointGroup::Torso].into_iter().chain(arms).chain([JointGroup::UpperBody]),
        )
    }

    /// The group's storage position: platform 0, torso 1, upper body 2, arm `a` at `3 + a`.
    pub const fn index(self) -> usize {
        match self {
            JointGroup::Platform => 0,
            JointGroup::Torso => 1,
            JointGroup::UpperBody => 2,
            JointGroup::Arm(arm) => 3 + arm.index(),
        }
    }
}

/// Which frames and coordinates belong to which part of a robot with `A` arms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotLayout<const N: usize, const A: usize> {
    /// The TCP frames, per arm ([`ArmId`]).
    pub tcp: PerArm<FrameId, A>,
    /// The platform coordinates; admitted axes are driven by the admittance. A fixed base has
    /// every axis [`Absent`](crate::platform::PlatformAxis::Absent).
    pub platform: PlatformLayout,
    /// Torso coordinates, `None` without a torso.
    pub torso: Option<[bool; N]>,
    /// Arm coordinates, per arm ([`ArmId`]).
    pub arms: PerArm<[bool; N], A>,
}

impl<const N: usize, const A: usize> RobotLayout<N, A> {
    /// The coordinates of `group` (all `false` for an arm the robot does not have).
    pub fn coordinates(&self, group: JointGroup) -> [bool; N] {
        match group {
            JointGroup::Torso => self.torso.unwrap_or([false; N]),
            JointGroup::Arm(arm) => arm.of(&self.arms).copied().unwrap_or([false; N]),
            JointGroup::Platform | JointGroup::UpperBody => {
                // The platform coordinates from the (at most three) platform axes.
                let platform = group == JointGroup::Platform;
                let mut mask = [!platform; N];
                for c in self.platform.axes().iter().filter_map(|a| a.coordinate()) {
                    if let Some(m) = mask.get_mut(c) {
                        *m = platform;
                    }
                }
                mask
            }
        }
    }

    /// The groups that have coordinates, in the order of [`JointGroup::all`].
    pub fn groups(&self) -> Vec<JointGroup, MAX_GROUPS> {
        collect_truncated(
            JointGroup::all::<A>().iter().copied().filter(|group| self.coordinates(*group).contains(&true)),
        )
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::{ArmId, JointGroup, RobotLayout};
    use crate::model::FrameId;
    use crate::platform::{PlatformAxis, PlatformLayout};

    #[test]
    fn group_indices_follow_storage_order() {
        let indices: std::vec::Vec<usize> = JointGroup::all::<2>().iter().map(|g| g.index()).collect();
        assert_eq!(indices, [0, 1, 3, 4, 2]);
        assert_eq!(JointGroup::all::<1>().len(), 4);
        assert_eq!(JointGroup::all::<4>().len(), 7);
    }

    #[test]
    fn arms_pick_their_index() {
        let mut per_arm = [10, 20];
        for arm in ArmId::all::<2>() {
            assert_eq!(arm.of(&per_arm), per_arm.get(arm.index()));
            *arm.of_mut(&mut per_arm).unwrap() += 1;
        }
        assert_eq!(per_arm, [11, 21]);
        assert_eq!(ArmId(2).of(&per_arm), None);
        assert_eq!(ArmId::all::<2>(), [ArmId::RIGHT, ArmId::LEFT]);
    }

    /// [`RobotLayout::coordinates`] against the per-coordinate definition (platform: a
    /// platform axis drives it; upper body: none does; torso and arms: their masks).
    #[test]
    fn coordinates_match_the_per_coordinate_definition() {
        let layouts = [
            PlatformLayout::try_new::<7>([PlatformAxis::Admitted(0), PlatformAxis::Admitted(1), PlatformAxis::Absent])
                .unwrap(),
            PlatformLayout::try_new::<7>([PlatformAxis::Absent, PlatformAxis::Absent, PlatformAxis::Absent]).unwrap(),
            PlatformLayout::try_new::<7>([PlatformAxis::Admitted(4), PlatformAxis::Absent, PlatformAxis::Admitted(6)])
                .unwrap(),
        ];
        for platform in layouts {
            let layout = RobotLayout::<7, 2> {
                tcp: [FrameId(0), FrameId(1)],
                platform,
                torso: Some([false, false, true, false, false, false, false]),
                arms: [
                    [false, false, false, true, false, false, false],
                    [false, false, false, false, false, true, false],
                ],
            };
            for group in JointGroup::all::<2>().into_iter().chain([JointGroup::Arm(ArmId(2))]) {
                let expected: [bool; 7] = core::array::from_fn(|i| match group {
                    JointGroup::Platform => layout.platform.is_platform(i),
                    JointGroup::UpperBody => !layout.platform.is_platform(i),
                    JointGroup::Torso => layout.torso.unwrap()[i],
                    JointGroup::Arm(arm) => arm.of(&layout.arms).is_some_and(|mask| mask[i]),
                });
                assert_eq!(layout.coordinates(group), expected, "{group:?}");
            }
        }
    }

    /// A fixed-base arm: no platform, no torso, one arm; its groups are the arm and the upper
    /// body (every coordinate).
    #[test]
    fn a_fixed_base_arm_has_only_its_arm_and_the_upper_body() {
        let absent = [PlatformAxis::Absent; 3];
        let layout = RobotLayout::<3, 1> {
            tcp: [FrameId(3)],
            platform: PlatformLayout::try_new::<3>(absent).unwrap(),
            torso: None,
            arms: [[true; 3]],
        };
        assert_eq!(layout.groups().as_slice(), [JointGroup::Arm(ArmId::RIGHT), JointGroup::UpperBody]);
        assert_eq!(layout.coordinates(JointGroup::Platform), [false; 3]);
        assert_eq!(layout.coordinates(JointGroup::UpperBody), [true; 3]);
    }
}
