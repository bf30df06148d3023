//! `include/cgcontact.h` is what cbindgen generates from the sources now: a stale header fails the
//! workspace's tests. `CGCONTACT_BLESS=1` rewrites it.

use std::path::Path;

#[test]
fn checked_in_header_is_up_to_date() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config =
        cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut generated);
    let generated = String::from_utf8(generated).expect("the header is UTF-8");
    let path = crate_dir.join("include/cgcontact.h");
    if std::env::var_os("CGCONTACT_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("write include/cgcontact.h");
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "include/cgcontact.h is stale: regenerate it with\n  CGCONTACT_BLESS=1 cargo test -p cgcontact-capi --test header\nand commit it"
    );
}
