//! An imported robot's collision file (`fixtures/robots/<name>/<name>.collision`, written by
//! `host-sim import`) read without `std`: the volumes attached to the bodies of their link
//! frames, every pair enabled except the kernel's rules and the file's `exclude` lines. The
//! measured images compile the file in (`include_str!`) and build the model once before the
//! measurement, so a re-import changes the measured model without a Rust edit.

use kernel::tasks::collision::{CollisionModel, CollisionModelBuilder, SweptSphere, VolumeId};
use kernel::Model;
use nalgebra::{convert, RealField, Vector3};

/// Most `exclude` lines a file may have.
pub const MAX_EXCLUDED: usize = 256;

/// The collision model of `text` (the file's format) for `model`, whose frame `i` is at the
/// origin of the URDF link `frame_names[i]`; `None` if a line does not parse, names an unknown
/// link or volume, or the model does not build with the capacities `V` and `P`.
pub fn collision_model<
    T: RealField + Copy,
    const N: usize,
    const B: usize,
    const F: usize,
    const V: usize,
    const P: usize,
>(
    text: &str,
    model: &Model<T, N, B, F>,
    frame_names: &[&str; F],
) -> Option<CollisionModel<T, V, P>> {
    let mut builder = CollisionModelBuilder::<T, V, P>::new();
    let mut names = [""; V];
    let mut excluded = [(VolumeId(0), VolumeId(0)); MAX_EXCLUDED];
    let mut excluded_count = 0;
    for line in text.lines() {
        let mut tokens = line.split('#').next()?.split_whitespace();
        match tokens.next() {
            None => {}
            Some("exclude") => {
                let mut volume = || tokens.next().and_then(|name| names.iter().position(|n| *n == name));
                let pair = (VolumeId(volume()?), VolumeId(volume()?));
                *excluded.get_mut(excluded_count)? = pair;
                excluded_count += 1;
            }
            Some(kind) => {
                let name = tokens.next()?;
                let _group = tokens.next()?;
                let link = tokens.next()?;
                let frame = model.frame(kernel::FrameId(frame_names.iter().position(|n| *n == link)?))?;
                let mut number = || tokens.next()?.parse::<f64>().ok().map(convert::<f64, T>);
                let radius = number()?;
                let mut point = || {
                    let local = Vector3::new(number()?, number()?, number()?);
                    Some(frame.placement.rotation * local + frame.placement.translation.vector)
                };
                let shape = match kind {
                    "sphere" => SweptSphere::sphere(point()?, radius),
                    "capsule" => SweptSphere::capsule(point()?, point()?, radius),
                    "triangle" => SweptSphere::swept_triangle(point()?, point()?, point()?, radius),
                    _ => return None,
                };
                let id = builder.add_volume(frame.parent, shape).ok()?;
                *names.get_mut(id.0)? = name;
            }
        }
    }
    builder.try_build(model, excluded.get(..excluded_count)?).ok()
}
