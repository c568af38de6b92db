//! The committed header must be exactly what cbindgen generates from the sources
//! (build.rs writes a fresh one to OUT_DIR on every build).

#[test]
fn committed_header_matches_cbindgen_output() {
    let generated = include_str!(concat!(env!("OUT_DIR"), "/baffle.h"));
    let committed_path = concat!(env!("CARGO_MANIFEST_DIR"), "/include/baffle.h");
    let committed = std::fs::read_to_string(committed_path).expect("include/baffle.h is committed");
    assert!(
        committed == generated,
        "{committed_path} differs from cbindgen's output; regenerate it with \
         `BAFFLE_UPDATE_HEADER=1 cargo build -p baffle-capi` and commit it"
    );
}
