//! Which frames and coordinates belong to which part of the robot: the two hands, the joint
//! groups and the [`RobotLayout`] that maps them to coordinates and TCP frames.

use crate::model::FrameId;
use crate::platform::PlatformLayout;

/// One entry per hand, indexed by [`Hand`] ([`Hand::of`], [`Hand::of_mut`], [`Hand::index`]):
/// the right hand's first.
pub type PerHand<X> = [X; 2];

/// One of the two hands (TCPs, arms).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum Hand {
    /// The right hand.
    Right,
    /// The left hand.
    Left,
}

impl Hand {
    /// Both hands, in [`PerHand`] order.
    pub const BOTH: [Hand; 2] = [Hand::Right, Hand::Left];

    /// The hand's position in a [`PerHand`] array: `0` for the right hand, `1` for the left.
    pub const fn index(self) -> usize {
        match self {
            Hand::Right => 0,
            Hand::Left => 1,
        }
    }

    /// This hand's entry of `per_hand`.
    pub fn of<X>(self, per_hand: &PerHand<X>) -> &X {
        let [right, left] = per_hand;
        match self {
            Hand::Right => right,
            Hand::Left => left,
        }
    }

    /// This hand's entry of `per_hand`, mutable.
    pub fn of_mut<X>(self, per_hand: &mut PerHand<X>) -> &mut X {
        let [right, left] = per_hand;
        match self {
            Hand::Right => right,
            Hand::Left => left,
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
    Arm(Hand),
    /// Torso and both arms.
    UpperBody,
}

impl JointGroup {
    /// Every group.
    pub const ALL: [JointGroup; 5] = [
        JointGroup::Platform,
        JointGroup::Torso,
        JointGroup::Arm(Hand::Right),
        JointGroup::Arm(Hand::Left),
        JointGroup::UpperBody,
    ];

    /// The group's position in [`Self::ALL`].
    pub const fn index(self) -> usize {
        match self {
            JointGroup::Platform => 0,
            JointGroup::Torso => 1,
            JointGroup::Arm(Hand::Right) => 2,
            JointGroup::Arm(Hand::Left) => 3,
            JointGroup::UpperBody => 4,
        }
    }
}

/// Which frames and coordinates belong to which part of the robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotLayout<const N: usize> {
    /// The TCP frames, per [`Hand`].
    pub tcp: PerHand<FrameId>,
    /// The platform coordinates; admitted axes are driven by the admittance.
    pub platform: PlatformLayout,
    /// Torso coordinates.
    pub torso: [bool; N],
    /// Arm coordinates, per [`Hand`].
    pub arms: PerHand<[bool; N]>,
}

impl<const N: usize> RobotLayout<N> {
    /// The coordinates of `group`.
    pub fn coordinates(&self, group: JointGroup) -> [bool; N] {
        match group {
            JointGroup::Torso => self.torso,
            JointGroup::Arm(hand) => *hand.of(&self.arms),
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
}

#[cfg(test)]
mod tests {
    use super::{Hand, JointGroup};

    #[test]
    fn group_indices_follow_all() {
        for (i, group) in JointGroup::ALL.iter().enumerate() {
            assert_eq!(group.index(), i);
        }
    }

    #[test]
    fn hands_pick_their_index() {
        let mut per_hand = [10, 20];
        for hand in Hand::BOTH {
            assert_eq!(Some(hand.of(&per_hand)), per_hand.get(hand.index()));
            *hand.of_mut(&mut per_hand) += 1;
        }
        assert_eq!(per_hand, [11, 21]);
    }

    /// [`super::RobotLayout::coordinates`] against the per-coordinate definition (platform: a
    /// platform axis drives it; upper body: none does; torso and arms: their masks).
    #[test]
    fn coordinates_match_the_per_coordinate_definition() {
        #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
        use crate::model::FrameId;
        use crate::platform::{PlatformAxis, PlatformLayout};
        let layouts = [
            PlatformLayout::try_new::<7>([PlatformAxis::Admitted(0), PlatformAxis::Admitted(1), PlatformAxis::Absent])
                .unwrap(),
            PlatformLayout::try_new::<7>([PlatformAxis::Absent, PlatformAxis::Absent, PlatformAxis::Absent]).unwrap(),
            PlatformLayout::try_new::<7>([PlatformAxis::Admitted(4), PlatformAxis::Absent, PlatformAxis::Admitted(6)])
                .unwrap(),
        ];
        for platform in layouts {
            let layout = super::RobotLayout::<7> {
                tcp: [FrameId(0), FrameId(1)],
                platform,
                torso: [false, false, true, false, false, false, false],
                arms: [
                    [false, false, false, true, false, false, false],
                    [false, false, false, false, false, true, false],
                ],
            };
            for group in JointGroup::ALL {
                let expected: [bool; 7] = core::array::from_fn(|i| match group {
                    JointGroup::Platform => layout.platform.is_platform(i),
                    JointGroup::UpperBody => !layout.platform.is_platform(i),
                    JointGroup::Torso => layout.torso[i],
                    JointGroup::Arm(hand) => hand.of(&layout.arms)[i],
                });
                assert_eq!(layout.coordinates(group), expected, "{group:?}");
            }
        }
    }
}
