//! Generates `baffle.h` with cbindgen on every build of the C ABI.
//!
//! The header goes to `$OUT_DIR/baffle.h` (the test `header.rs` compares it with the
//! committed `include/baffle.h`) and to `<target>/<profile>/include/baffle.h`, where
//! CMake picks it up. `BAFFLE_UPDATE_HEADER=1` also rewrites the committed header.

use std::path::{Path, PathBuf};

fn main() {
    let crate_dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo:rerun-if-changed=src");
    println!("cargo:rerun-if-changed=cbindgen.toml");
    println!("cargo:rerun-if-env-changed=BAFFLE_UPDATE_HEADER");

    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml is valid");
    let bindings = cbindgen::Builder::new()
        .with_crate(&crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen can parse the C ABI");
    let mut text = Vec::new();
    bindings.write(&mut text);

    write_if_changed(&out_dir.join("baffle.h"), &text);
    // OUT_DIR is <target>/<profile>/build/<pkg>-<hash>/out.
    if let Some(profile_dir) = out_dir.ancestors().nth(3) {
        write_if_changed(&profile_dir.join("include").join("baffle.h"), &text);
    }
    if std::env::var("BAFFLE_UPDATE_HEADER").is_ok_and(|v| v == "1") {
        write_if_changed(&crate_dir.join("include").join("baffle.h"), &text);
    }
    // A SONAME lets executables linked against the shared library find it by name.
    if std::env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "linux") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libbaffle.so");
    }
}

/// Rewriting an unchanged header would make CMake rebuild everything that includes it.
fn write_if_changed(path: &Path, text: &[u8]) {
    if std::fs::read(path).is_ok_and(|old| old == text) {
        return;
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).expect("can create the header directory");
    }
    std::fs::write(path, text).expect("can write the generated header");
}
