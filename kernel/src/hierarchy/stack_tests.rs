//! The rows a task writes through a [`TaskWindow`] against the plain path: the same rows built
//! in an owned [`TaskRows`] and put on the stack with [`Stack::push_rows`], [`push_scaled`] and
//! [`push_transitioning`] (one copy per row).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]

use super::*;
use crate::hierarchy::{push_scaled, push_transitioning};
use nalgebra::{convert, RealField};

const N: usize = 5;
const Q: usize = 6;
const R: usize = 16;

/// A small deterministic generator (splitmix64) of values in `[-1, 1)`.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// One row the writer appends: how (`kind` 0: `push` of a built row, 1: `push_with` writing one
/// entry into the zero row, 2: `push_with_metric` writing the whole row and its metric) and the
/// values.
#[derive(Clone, Copy)]
struct Spec {
    kind: u8,
    entry: usize,
    values: [f64; N],
    force: f64,
    potential: f64,
    activation: f64,
    metric: f64,
}

fn random_specs(rng: &mut Rng, count: usize) -> std::vec::Vec<Spec> {
    (0..count)
        .map(|_| Spec {
            kind: (rng.unit().abs() * 3.0) as u8 % 3,
            entry: (rng.unit().abs() * N as f64) as usize % N,
            values: core::array::from_fn(|_| 3.0 * rng.unit()),
            force: 50.0 * rng.unit(),
            potential: rng.unit().abs(),
            activation: rng.unit().abs(),
            metric: 0.1 + rng.unit().abs(),
        })
        .collect()
}

/// Appends the rows of `specs` to `sink` with the sink's own methods.
fn write<T: RealField + Copy, const M: usize>(sink: &mut impl RowSink<T, N, M>, specs: &[Spec]) {
    let c = |x: f64| convert::<f64, T>(x);
    for s in specs {
        match s.kind {
            0 => sink
                .push(TaskRow {
                    jacobian: RowSVector::from_fn(|_, j| c(s.values[j])),
                    force: c(s.force),
                    potential: c(s.potential),
                    activation: c(s.activation),
                })
                .unwrap(),
            1 => sink
                .push_with(s.entry..s.entry + 1, |row| {
                    row.jacobian[0] = c(s.values[s.entry]);
                    row.force = c(s.force);
                    row.activation = c(s.activation);
                })
                .unwrap(),
            _ => sink
                .push_with_metric(|row| {
                    for (x, &v) in row.jacobian.iter_mut().zip(&s.values) {
                        *x = c(v);
                    }
                    row.force = c(s.force);
                    row.potential = c(s.potential);
                    row.activation = c(s.activation);
                    Some(c(s.metric))
                })
                .unwrap(),
        }
    }
}

/// A stack whose slots all hold rows of an earlier cycle (nonzero, with metrics), then cleared.
fn stale<T: RealField + Copy>(rng: &mut Rng) -> Stack<T, N, R> {
    let mut stack = Stack::new();
    let mut window = stack.task::<R>();
    let mut specs = random_specs(rng, R);
    for s in specs.iter_mut() {
        s.kind = 2;
    }
    write(&mut window, &specs);
    window.place(3).unwrap();
    assert_eq!(stack.rows().len(), R);
    stack.clear();
    stack
}

/// `stack` with every row's support widened to all columns (as a [`TaskRows`] list's rows
/// have it on the stack), after checking that each row is zero outside its support.
fn full_support<T: RealField + Copy>(stack: &Stack<T, N, R>) -> Stack<T, N, R> {
    let mut full = stack.clone();
    for slot in full.slots.iter_mut().take(full.len) {
        let (first, end) = slot.support;
        let outside = slot.row.jacobian.iter().enumerate().filter(|(i, _)| *i < first || *i >= end);
        assert!(outside.clone().all(|(_, &x)| x == T::zero()), "support {:?}", slot.support);
        slot.support = (0, N);
    }
    full
}

/// How a task's rows are placed.
#[derive(Clone, Copy, Debug)]
enum Placement {
    Level(usize),
    Scaled(usize, f64),
    Transition(usize, usize, f64),
}

/// On random rows over stale slots: a task written through a window and placed equals the same
/// rows built in an owned list and pushed (bit for bit: rows, levels, weights, carried metrics,
/// level count), after rows of earlier tasks; the window's rows before placement are the list's.
fn window_equals_owned_list<T: RealField + Copy>() {
    let mut rng = Rng(0x5EED_0013);
    let placements = [
        Placement::Level(0),
        Placement::Level(2),
        Placement::Scaled(1, 0.37),
        Placement::Scaled(1, 1.0),
        Placement::Scaled(2, 1.5),
        Placement::Scaled(0, 0.0),
        Placement::Transition(0, 1, 0.0),
        Placement::Transition(0, 1, 0.3),
        Placement::Transition(2, 0, 0.71),
        Placement::Transition(1, 0, 1.0),
    ];
    let (mut compared, mut narrow) = (0, 0);
    for trial in 0..40 {
        let placement = placements[trial % placements.len()];
        let (earlier, task) = (random_specs(&mut rng, 3), random_specs(&mut rng, 1 + trial % 4));
        let mut plain = Stack::<T, N, R>::new();
        let mut fast = stale::<T>(&mut rng);
        for (level, stack) in [(1, &mut plain), (1, &mut fast)] {
            let mut list = TaskRows::<T, N, Q>::new();
            write(&mut list, &earlier);
            stack.push_rows(level, &list).unwrap();
        }
        let mut list = TaskRows::<T, N, Q>::new();
        write(&mut list, &task);
        let mut window = fast.task::<Q>();
        write(&mut window, &task);
        assert_eq!(window.rows().len(), list.len());
        for ((slot, row), metric) in window.rows().iter().zip(list.rows()).zip(list.metric_norm_squared()) {
            assert_eq!((&slot.row, slot.metric_norm_squared), (row, *metric));
        }
        match placement {
            Placement::Level(level) => {
                plain.push_rows(level, &list).unwrap();
                window.place(level).unwrap();
            }
            Placement::Scaled(level, w) => {
                push_scaled(&mut plain, &list, level, convert(w)).unwrap();
                window.place_scaled(level, convert(w)).unwrap();
            }
            Placement::Transition(from, to, progress) => {
                push_transitioning(&mut plain, &list, from, to, convert(progress)).unwrap();
                window.place_transitioning(from, to, convert(progress)).unwrap();
            }
        }
        narrow += fast.rows().iter().filter(|r| r.support != (0, N)).count();
        assert_eq!(full_support(&fast), plain, "trial {trial}: {placement:?}");
        assert!(fast.rows().len() >= 3 && fast.level_count() >= 2);
        compared += fast.rows().len();
    }
    // Not vacuous: the transitions put rows on two levels, the zero weight removes them.
    assert!(compared > 150 && narrow > 30, "{compared} rows compared, {narrow} with one column");
}

#[test]
fn window_equals_owned_list_f64() {
    window_equals_owned_list::<f64>();
}

#[test]
fn window_equals_owned_list_f32() {
    window_equals_owned_list::<f32>();
}

/// A window refuses non-finite rows and rows beyond the task's capacity `Q` or the stack's free
/// slots (telling the two apart), removes its rows when dropped unplaced, on a zero or
/// non-finite weight and when a transition's copy does not fit; `push_with` sees a zero row
/// over a stale slot.
#[test]
fn window_errors_leave_the_stack_unchanged() {
    let mut rng = Rng(7);
    let mut stack = stale::<f64>(&mut rng);
    let mut list = TaskRows::<f64, N, Q>::new();
    write(&mut list, &random_specs(&mut rng, 4));
    stack.push_rows(0, &list).unwrap();
    let before = stack.clone();

    let mut window = stack.task::<Q>();
    window
        .push_with(2..5, |row| {
            assert_eq!((&*row.jacobian, row.force, row.potential, row.activation), (&[0.0; 3][..], 0.0, 0.0, 0.0));
            row.force = 1.0;
        })
        .unwrap();
    assert_eq!(window.rows()[0].row.jacobian, RowSVector::<f64, N>::zeros(), "the stale slot's row is cleared");
    assert_eq!(window.rows()[0].support, (2, 5));
    assert_eq!(window.push_with(0..1, |row| row.potential = f64::NAN), Err(TaskError::NonFinite));
    assert_eq!(window.push_with(1..2, |row| row.jacobian[0] = f64::NAN), Err(TaskError::NonFinite));
    assert_eq!(
        window.push_with_metric(|row| {
            row.jacobian[0] = f64::INFINITY;
            None
        }),
        Err(TaskError::NonFinite)
    );
    let nan = TaskRow { jacobian: RowSVector::zeros(), force: f64::NAN, potential: 0.0, activation: 1.0 };
    assert_eq!(window.push(nan), Err(TaskError::NonFinite));
    assert_eq!(window.len(), 1);
    for _ in 1..Q {
        window.push_with(0..N, |row| row.force = 2.0).unwrap();
    }
    assert_eq!(window.push_with(0..N, |row| row.force = 3.0), Err(TaskError::Capacity { capacity: Q }));
    assert_eq!(window.overflow(), None);
    window.truncate(2);
    assert_eq!(window.len(), 2);
    drop(window);
    assert_eq!(stack, before);

    for weight in [0.0, -1.0] {
        let mut window = stack.task::<Q>();
        write(&mut window, &random_specs(&mut rng, 2));
        window.place_scaled(1, weight).unwrap();
        assert_eq!(stack, before);
    }
    let mut window = stack.task::<Q>();
    write(&mut window, &random_specs(&mut rng, 2));
    assert_eq!(window.place_scaled(1, f64::NAN), Err(HierarchyError::NonFinite));
    assert_eq!(stack, before);
    let mut window = stack.task::<Q>();
    write(&mut window, &random_specs(&mut rng, 2));
    assert_eq!(window.place_transitioning(0, 1, f64::INFINITY), Err(HierarchyError::NonFinite));
    assert_eq!(stack, before);

    // The stack's free slots run out before the task's capacity: with 10 rows on the stack, a
    // transition of 4 rows needs 8 slots (6 free), and after 3 more rows a task finds 3 free.
    let mut window = stack.task::<Q>();
    write(&mut window, &random_specs(&mut rng, Q));
    window.place(2).unwrap();
    let filled = stack.clone();
    let mut window = stack.task::<Q>();
    write(&mut window, &random_specs(&mut rng, 4));
    assert_eq!(window.place_transitioning(0, 1, 0.5), Err(HierarchyError::Capacity { capacity: R }));
    assert_eq!(stack, filled);
    let mut window = stack.task::<Q>();
    write(&mut window, &random_specs(&mut rng, 3));
    window.place(1).unwrap();
    let filled = stack.clone();
    let mut window = stack.task::<Q>();
    write(&mut window, &random_specs(&mut rng, 3));
    assert_eq!(window.push_with(0..1, |row| row.force = 1.0), Err(TaskError::Capacity { capacity: Q }));
    assert_eq!(window.overflow(), Some(HierarchyError::Capacity { capacity: R }));
    drop(window);
    assert_eq!(stack, filled);
    assert_eq!(stack.rows().len(), 4 + Q + 3);
}
