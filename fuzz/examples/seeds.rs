//! Writes the committed seed corpora of the fuzz targets (`fuzz/corpus/<target>/`): one valid
//! encoding of each planner command kind in f64 and f32, a few frame sequences, and the
//! repository's URDFs and a states file. Run from `fuzz/`: `cargo run --example seeds`.

use fixtures::justin::whole_body;
use heapless::Vec;
use kernel::controller::config::{ArmId, CollisionFieldParameters, Consistency, Field, JointGroup};
use kernel::controller::messages::{encode_command, Command, Pose};
use serde::Serialize;
use std::fs;
use std::path::Path;

fn commands<T: nalgebra::RealField + Copy>() -> [Command<T>; 7] {
    let c = nalgebra::convert::<f64, T>;
    let pose = Pose { position: [c(0.6), c(-0.3), c(1.0)], orientation: [c(1.0), c(0.0), c(0.0), c(0.0)] };
    [
        Command::SetHierarchy(Vec::from_slice(&whole_body::fig_6_3_hierarchy(ArmId::LEFT)).unwrap_or_default()),
        Command::SetCartesian { hand: ArmId::RIGHT, parameters: whole_body::chapter_6_cartesian() },
        Command::SetCollisionField {
            field: Field::Weak,
            parameters: CollisionFieldParameters {
                max_force: c(50.0),
                influence_distance: c(0.1),
                damping_ratio: c(0.7),
                activation_full: c(0.02),
                activation_zero: c(0.08),
            },
        },
        Command::SetConsistency(Consistency::Static),
        Command::TcpGoal { hand: ArmId::LEFT, pose, duration_s: c(1.5) },
        Command::TcpSample { hand: ArmId::RIGHT, pose, linear_velocity: [c(0.1); 3], angular_velocity: [c(0.0); 3] },
        Command::JointGoal {
            group: JointGroup::Platform,
            values: Vec::from_slice(&[c(0.1), c(-0.2), c(0.3)]).unwrap_or_default(),
            duration_s: c(2.0),
        },
    ]
}

fn write_commands<T: nalgebra::RealField + Copy + Serialize>(dir: &Path, scalar: &str) {
    let mut buffer = [0_u8; 2048];
    for (i, command) in commands::<T>().iter().enumerate() {
        let bytes = encode_command(command, &mut buffer).expect("seed commands encode");
        fs::write(dir.join(format!("{scalar}-{i}")), &*bytes).expect("writable corpus");
    }
}

/// One revolute joint with a link and a fixed tool.
const TINY_URDF: &str = r#"<robot name="r"><link name="base"/>
<link name="arm"><inertial><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
<link name="tool"><inertial><mass value="0.5"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
<joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="10" velocity="1"/></joint>
<joint name="flange" type="fixed"><parent link="arm"/><child link="tool"/><origin xyz="0.4 0 0" rpy="0 0.1 0"/></joint>
</robot>"#;

fn main() {
    let corpus = Path::new("corpus");
    let command_dir = corpus.join("command_apply");
    fs::create_dir_all(&command_dir).expect("writable corpus");
    write_commands::<f64>(&command_dir, "f64");
    write_commands::<f32>(&command_dir, "f32");

    // Frame sequences: 48 cycles near home (the bytes are small deviations), one with a
    // command between cycles, one with jumps of the counters.
    let steps = corpus.join("step_sequence");
    fs::create_dir_all(&steps).expect("writable corpus");
    let quiet: std::vec::Vec<u8> = (0..48 * 80).map(|i| (i * 37 % 11) as u8).collect();
    fs::write(steps.join("quiet"), &quiet).expect("writable corpus");
    let mut with_command = vec![0_u8; 200];
    let mut buffer = [0_u8; 2048];
    let goal = &commands::<f32>()[4];
    let bytes = encode_command(goal, &mut buffer).expect("seed commands encode");
    with_command.extend_from_slice(&[0xff, bytes.len() as u8]);
    with_command.extend_from_slice(bytes);
    with_command.extend((0..2000).map(|i| (i * 13 % 7) as u8));
    fs::write(steps.join("goal"), &with_command).expect("writable corpus");
    let jumps: std::vec::Vec<u8> = (0..4000).map(|i| (i * 101 % 251) as u8).collect();
    fs::write(steps.join("jumps"), &jumps).expect("writable corpus");

    let parsers = corpus.join("host_parsers");
    fs::create_dir_all(&parsers).expect("writable corpus");
    let panda = fs::read("../fixtures/urdf/panda.urdf").expect("the Panda URDF is in fixtures/urdf");
    fs::write(parsers.join("panda.urdf"), panda).expect("writable corpus");
    fs::write(parsers.join("tiny.urdf"), TINY_URDF).expect("writable corpus");
    fs::write(parsers.join("states.json"), r#"[{"q": [0.1], "v": [-2.5e-3]}, {"q": [1e300], "v": [0]}]"#)
        .expect("writable corpus");
}
