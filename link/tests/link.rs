//! The link's frames survive encoding, and every kind of bad input gives its typed error.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]

use link::{
    encode, write_frame, ActuatorMsg, Frame, FrameReader, Joints, LinkError, LinkFault, OutputMode, Payload, Received,
    RuntimeStats, SensorMsg, MAX_ENCODED,
};
use proptest::prelude::*;

fn sensor(seq: u32, n: usize, value: f32) -> Frame {
    let joints: Joints = (0..n).map(|i| value + i as f32).collect();
    Frame {
        seq,
        payload: Payload::Sensor(SensorMsg {
            cycle: u64::from(seq) + 1,
            position: joints.clone(),
            velocity: joints.clone(),
            torque: joints,
            pose: [1.0, -2.0, 0.5],
            base_velocity: [0.0, 0.1, -0.1],
            leg_lengths: [0.4; hal::LEGS],
        }),
    }
}

fn wire(frame: &Frame) -> Vec<u8> {
    let mut out = [0u8; MAX_ENCODED];
    encode(frame, &mut out).unwrap().to_vec()
}

/// Every frame result the reader produces from `bytes`.
fn read_all(reader: &mut FrameReader, bytes: &[u8]) -> Vec<Result<Received, LinkError<()>>> {
    bytes.iter().filter_map(|b| reader.push(*b)).collect()
}

#[test]
fn a_frame_is_cobs_with_one_terminating_zero() {
    let bytes = wire(&sensor(0, 17, 0.0));
    assert_eq!(bytes.last(), Some(&0));
    assert_eq!(bytes.iter().filter(|b| **b == 0).count(), 1);
    // 17 joints × 3 × 4 bytes + platform 10 × 4 + cycle, seq, tags, vec lengths, CRC, COBS.
    assert!((250..270).contains(&bytes.len()), "{} bytes", bytes.len());
}

#[test]
fn writes_and_reads_through_embedded_io() {
    let frames = [sensor(7, 17, 0.5), sensor(8, 3, -1.0)];
    let mut buffer = [0u8; 2 * MAX_ENCODED];
    let mut port: &mut [u8] = &mut buffer;
    for frame in &frames {
        write_frame(&mut port, frame).unwrap();
    }
    let left = port.len();
    let mut input: &[u8] = &buffer[..2 * MAX_ENCODED - left];
    let mut reader = FrameReader::new();
    for frame in &frames {
        assert_eq!(reader.read(&mut input).unwrap(), Received { frame: frame.clone(), lost: 0 });
    }
    assert_eq!(reader.read(&mut input), Err(LinkError::Closed));
}

#[test]
fn a_flipped_bit_is_corrupted_and_the_next_frame_still_reads() {
    let mut reader = FrameReader::new();
    for position in [0, 1, 40, 200] {
        let mut bytes = wire(&sensor(position, 17, 0.0));
        bytes[position as usize] ^= 0x10;
        bytes.extend(wire(&sensor(position + 1, 17, 0.0)));
        let results = read_all(&mut reader, &bytes);
        assert_eq!(results.len(), 2, "bit flip at {position}");
        assert_eq!(results[0], Err(LinkError::Corrupted), "bit flip at {position}");
        assert_eq!(results[1].as_ref().map(|r| r.frame.seq), Ok(position + 1));
    }
}

#[test]
fn a_frame_cut_short_is_truncated_or_corrupted() {
    let bytes = wire(&sensor(300, 17, 0.0));
    // The COBS run boundaries: each code byte gives the distance to the next.
    let mut boundaries = vec![0];
    while let Some(&code) = bytes.get(*boundaries.last().unwrap()).filter(|c| **c != 0) {
        boundaries.push(boundaries.last().unwrap() + usize::from(code));
    }
    let cut = |end: usize| [&bytes[..end], &[0]].concat();
    let mut reader = FrameReader::new();
    // Cut inside the first COBS run (its code byte announces more bytes than follow).
    assert!(boundaries[1] >= 2);
    assert_eq!(read_all(&mut reader, &cut(boundaries[1] - 1)), vec![Err(LinkError::Truncated)]);
    // Complete COBS, but three bytes: less than a CRC.
    assert_eq!(read_all(&mut reader, &[4, 1, 2, 3, 0]), vec![Err(LinkError::Truncated)]);
    // Cut at a later run boundary: the last four bytes are taken for a CRC that does not match.
    let boundary = *boundaries.iter().find(|b| **b > 20).unwrap();
    let cut = cut(boundary);
    assert_eq!(read_all(&mut reader, &cut), vec![Err(LinkError::Corrupted)], "cut at {boundary}");
}

#[test]
fn an_oversized_frame_is_refused_and_costs_only_itself() {
    let mut bytes = vec![1u8; MAX_ENCODED + 10];
    bytes.push(0);
    bytes.extend(wire(&sensor(3, 17, 0.0)));
    let mut reader = FrameReader::new();
    let results = read_all(&mut reader, &bytes);
    assert_eq!(results[0], Err(LinkError::Oversized));
    assert_eq!(results[1].as_ref().map(|r| r.frame.seq), Ok(3));
}

#[test]
fn replayed_frames_are_refused_and_gaps_are_counted() {
    let mut reader = FrameReader::new();
    let mut bytes = wire(&sensor(10, 2, 0.0));
    bytes.extend(wire(&sensor(11, 2, 0.0)));
    bytes.extend(wire(&sensor(11, 2, 0.0)));
    bytes.extend(wire(&sensor(5, 2, 0.0)));
    bytes.extend(wire(&sensor(15, 2, 0.0)));
    let results = read_all(&mut reader, &bytes);
    let lost: Vec<_> = results.iter().map(|r| r.as_ref().map(|r| r.lost)).collect();
    assert_eq!(
        lost,
        vec![
            Ok(0),
            Ok(0),
            Err(&LinkError::Replayed { seq: 11, expected: 12 }),
            Err(&LinkError::Replayed { seq: 5, expected: 12 }),
            Ok(3)
        ]
    );
}

fn any_payload() -> impl Strategy<Value = Payload> {
    let joints = || prop::collection::vec(any::<f32>(), 0..=32).prop_map(|v| Joints::from_slice(&v).unwrap());
    let floats = |n: usize| prop::collection::vec(any::<f32>(), n);
    prop_oneof![
        (any::<u64>(), joints(), joints(), joints(), floats(10)).prop_map(|(cycle, position, velocity, torque, p)| {
            Payload::Sensor(SensorMsg {
                cycle,
                position,
                velocity,
                torque,
                pose: [p[0], p[1], p[2]],
                base_velocity: [p[3], p[4], p[5]],
                leg_lengths: [p[6], p[7], p[8], p[9]],
            })
        }),
        (any::<u64>(), joints(), floats(7), any::<bool>(), 0u8..3, any::<u8>(), 0u8..6).prop_map(
            |(cycle, torque, p, brake, mode, fault_code, link)| {
                Payload::Actuator(ActuatorMsg {
                    cycle,
                    torque,
                    base_velocity: [p[0], p[1], p[2]],
                    leg_rates: [p[3], p[4], p[5], p[6]],
                    brake,
                    mode: [OutputMode::Normal, OutputMode::Hold, OutputMode::Brake][mode as usize],
                    fault_code,
                    link_fault: [
                        LinkFault::Corrupted,
                        LinkFault::Truncated,
                        LinkFault::Oversized,
                        LinkFault::Replayed,
                        LinkFault::Missing,
                    ]
                    .get(link as usize)
                    .copied(),
                })
            }
        ),
        prop::collection::vec(any::<u8>(), 0..=300).prop_map(|b| Payload::Command(b.as_slice().try_into().unwrap())),
        prop::collection::vec(any::<u8>(), 0..=300).prop_map(|b| Payload::Telemetry(b.as_slice().try_into().unwrap())),
        (any::<u64>(), any::<u32>(), any::<u32>(), any::<u32>()).prop_map(
            |(cycles, deadline_misses, worst_cycle_cost, link_faults)| {
                Payload::Stats(RuntimeStats { cycles, deadline_misses, worst_cycle_cost, link_faults })
            }
        ),
    ]
}

/// Equality with NaN payloads compared bit for bit.
fn same(a: &Frame, b: &Frame) -> bool {
    format!("{a:?}") == format!("{b:?}")
}

proptest! {
    #[test]
    fn every_frame_round_trips(seq in any::<u32>(), payload in any_payload()) {
        let frame = Frame { seq, payload };
        let mut reader = FrameReader::new();
        let results = read_all(&mut reader, &wire(&frame));
        prop_assert_eq!(results.len(), 1);
        let received = results[0].clone().unwrap();
        prop_assert!(same(&received.frame, &frame));
        prop_assert_eq!(received.lost, 0);
    }

    #[test]
    fn a_corrupted_byte_never_passes_as_a_frame(payload in any_payload(), at in any::<prop::sample::Index>(), flip in 1u8..=255) {
        let frame = Frame { seq: 1, payload };
        let mut bytes = wire(&frame);
        let n = bytes.len() - 1;
        bytes[at.index(n)] ^= flip;
        let mut reader = FrameReader::new();
        for result in read_all(&mut reader, &bytes) {
            // A CRC-32 detects every burst up to 32 bits: whatever the reader makes of the
            // bytes, it is an error, never a frame.
            prop_assert!(result.is_err(), "{:?}", result);
        }
    }

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
        let mut reader = FrameReader::new();
        let _ = read_all(&mut reader, &bytes);
    }
}
