//! Puts the repository's root `memory.x` (the one memory layout of the STM32F405RG)
//! on the linker's search path, where cortex-m-rt's `link.x` includes it.

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let manifest_dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let memory_x = manifest_dir.join("..").join("memory.x");
    let out_dir = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));

    // Copy into OUT_DIR rather than pointing at the root: the search path then holds
    // nothing but memory.x, so no other file there can shadow a linker script.
    fs::copy(&memory_x, out_dir.join("memory.x"))
        .unwrap_or_else(|e| panic!("cannot copy {}: {e}", memory_x.display()));
    println!("cargo:rustc-link-search={}", out_dir.display());

    // Relink when the layout changes.
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
}
