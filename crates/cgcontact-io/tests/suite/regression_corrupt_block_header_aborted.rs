//! Regression: a `.vtu` with zlib-compressed inline arrays whose block header had been corrupted (found
//! by `parser_property::mesh_parser_never_panics_on_mutated_files` with 5,000 cases) made vtkio allocate
//! 549,789,368,322 bytes, and the failed allocation aborted the process: no error value, no
//! `catch_unwind`. The block headers are now checked before vtkio sees the file.

use cgcontact_io::{DisplacementArray, parse_hex_mesh};

#[test]
fn corrupt_zlib_block_header_is_an_error_not_an_abort() {
    let bytes = include_bytes!("../../../../fixtures/regressions/corrupt-zlib-block-header.vtu");
    let error = parse_hex_mesh(bytes, &DisplacementArray::Default).unwrap_err();
    assert!(error.to_string().contains("compressed array"), "{error}");
}
