//! What the fuzz targets share: the Justin whole-body controller they drive (built once, cloned
//! per input), sensor frames decoded from fuzzer bytes, and the output contract
//! ([`thesis_tests::contract::check_output`]) every target asserts after every cycle.

use arbitrary::{Result, Unstructured};
use fixtures::justin::{self, collision, whole_body};
use hal::{JointSample, PlatformSample};
use kernel::controller::config::ArmId;
use kernel::controller::{SensorFrame, PLATFORM_DOF};
use nalgebra::RealField;
use std::sync::OnceLock;

pub use fixtures::justin::whole_body::JustinController;

/// Joints of the upper body (the frame's joint arrays).
pub const U: usize = justin::UPPER_DOF;

/// A Justin controller with the Fig. 6.3 hierarchy, started on the home pose (one valid cycle
/// run), so that planner input reaches a running controller.
pub fn started<T: RealField + Copy>() -> Box<JustinController<T>> {
    let model = justin::model::<T>().expect("Justin's model builds");
    let collision = collision::collision_model(&model).expect("Justin's collision model builds");
    let config = whole_body::controller_config::<T>().expect("Justin's configuration is valid");
    let hierarchy = whole_body::fig_6_3_hierarchy(ArmId::RIGHT);
    let mut controller =
        Box::new(JustinController::<T>::try_new(model, collision, config, &hierarchy).expect("the controller builds"));
    controller.step(&home_frame(1));
    controller
}

/// A clone of a controller built once per process and scalar.
pub fn cached<T: RealField + Copy>(cell: &'static OnceLock<Box<JustinController<T>>>) -> Box<JustinController<T>> {
    cell.get_or_init(started::<T>).clone()
}

/// The home pose at rest, with both cycle counters at `cycle`.
pub fn home_frame<T: RealField + Copy>(cycle: u64) -> SensorFrame<T, U> {
    let home = justin::home_configuration::<T>();
    let leg = nalgebra::convert::<f64, T>(justin::LEG_LENGTH_NOMINAL);
    SensorFrame {
        joints: JointSample {
            position: core::array::from_fn(|i| home.get(i + PLATFORM_DOF).copied().unwrap_or_else(T::zero)),
            velocity: [T::zero(); U],
            torque: [T::zero(); U],
            cycle,
        },
        platform: PlatformSample {
            pose: core::array::from_fn(|i| home.get(i).copied().unwrap_or_else(T::zero)),
            velocity: [T::zero(); 3],
            leg_lengths: [leg; 4],
            cycle,
        },
    }
}

/// A sensor frame from fuzzer bytes: the home pose plus small deviations (`i8` steps of
/// `scale`), a few values replaced by arbitrary `f64`s (NaN, ±inf, huge), and cycle counters
/// that mostly advance by one but may repeat, jump back or forward, or differ between joints and
/// platform. `last` is the last cycle the frame sequence used.
pub fn frame<T: RealField + Copy>(u: &mut Unstructured, last: &mut u64) -> Result<SensorFrame<T, U>> {
    let mut frame = home_frame::<f64>(0);
    let scale = [0.002, 0.02, 0.3, 3.0][usize::from(u.int_in_range(0..=3u8)?)];
    let deviate = |x: &mut f64, u: &mut Unstructured| -> Result<()> {
        *x += f64::from(u.arbitrary::<i8>()?) * scale / 127.0;
        Ok(())
    };
    for x in frame.joints.position.iter_mut().chain(frame.joints.velocity.iter_mut()) {
        deviate(x, u)?;
    }
    for x in frame.joints.torque.iter_mut() {
        *x = f64::from(u.arbitrary::<i8>()?) * scale * 20.0 / 127.0;
    }
    for x in frame.platform.pose.iter_mut().chain(frame.platform.velocity.iter_mut()) {
        deviate(x, u)?;
    }
    for _ in 0..u.int_in_range(0..=2u8)? {
        let value: f64 = u.arbitrary()?;
        let index = usize::from(u.arbitrary::<u8>()?);
        let slot = match u.int_in_range(0..=5u8)? {
            0 => frame.joints.position.get_mut(index % U),
            1 => frame.joints.velocity.get_mut(index % U),
            2 => frame.joints.torque.get_mut(index % U),
            3 => frame.platform.pose.get_mut(index % 3),
            4 => frame.platform.velocity.get_mut(index % 3),
            _ => frame.platform.leg_lengths.get_mut(index % 4),
        };
        if let Some(slot) = slot {
            *slot = value;
        }
    }
    let (joints, platform) = match u.int_in_range(0..=15u8)? {
        0 => (*last, *last),
        1 => {
            let back = u64::from(u.arbitrary::<u16>()?);
            (last.saturating_sub(back), last.saturating_sub(back))
        }
        2 => (*last + 2 + u64::from(u.arbitrary::<u8>()?), *last + 2),
        3 => {
            let any = u.arbitrary::<u64>()?;
            (any, any)
        }
        4 => (*last + 1, *last + 1 + u64::from(u.int_in_range(1..=4u8)?)),
        _ => (*last + 1, *last + 1),
    };
    // Keep room for the following cycles after a jump to the end of the range.
    *last = (*last).max(joints).min(u64::MAX / 2);
    let c = |a: &[f64; U]| -> [T; U] { a.map(nalgebra::convert) };
    Ok(SensorFrame {
        joints: JointSample {
            position: c(&frame.joints.position),
            velocity: c(&frame.joints.velocity),
            torque: c(&frame.joints.torque),
            cycle: joints,
        },
        platform: PlatformSample {
            pose: frame.platform.pose.map(nalgebra::convert),
            velocity: frame.platform.velocity.map(nalgebra::convert),
            leg_lengths: frame.platform.leg_lengths.map(nalgebra::convert),
            cycle: platform,
        },
    })
}

/// Panics (the fuzzer's failure) with the violation if the last output breaks the contract.
pub fn assert_contract<T: RealField + Copy>(controller: &JustinController<T>, context: &str) {
    if let Err(violation) = thesis_tests::contract::check_output(controller) {
        panic!("{context}: {violation}");
    }
}
