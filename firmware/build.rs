//! Puts the top-level `memory.x` on the linker search path (cortex-m-rt's `link.x` includes it)
//! and links the runtime image with defmt's `defmt.x`.
use std::{env, fs, path::PathBuf};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("OUT_DIR not set")?);
    fs::copy("../memory.x", out.join("memory.x"))?;
    println!("cargo:rustc-link-search={}", out.display());
    // defmt's linker script (its interned strings) for the image that logs through defmt.
    println!("cargo:rustc-link-arg-bin=runtime=-Tdefmt.x");
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    Ok(())
}
