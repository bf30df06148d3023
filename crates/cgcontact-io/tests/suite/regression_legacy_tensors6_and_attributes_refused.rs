//! VTK's legacy writer writes a tensor array of 6 components (a solver's strain or stress) as
//! `TENSORS6 name type`, a keyword vtkio's parser does not know: every such file was refused, as
//! "cannot parse `strain double`". And in a binary file the walk that finds the id sections and
//! string arrays to blank stopped at the first `TEXTURE_COORDINATES`, `TENSORS`, `COLOR_SCALARS`
//! or `LOOKUP_TABLE name size` section, which it did not measure, so a file with global ids after
//! one (VTK writes the id sections after those attributes) was refused as "unexpected
//! `GLOBAL_IDS ...` after the last complete section". Each file VTK 9.7.2 wrote with them
//! (fixtures/vtk-written-attributes, made by its make.py) now reads as the same body written
//! without them, bit for bit; a `TENSORS6` section that does not hold six values a node is an error
//! naming it and its line.

use std::path::PathBuf;

use crate::common::legacy_fixtures::{self, FLAVOURS, assert_same, parse, replaced};

fn folder() -> PathBuf {
    legacy_fixtures::folder("vtk-written-attributes")
}

fn file(name: &str) -> Vec<u8> {
    legacy_fixtures::read(&folder(), name)
}

#[test]
fn tensors6_and_the_attributes_before_id_sections_read_in_every_flavour() {
    for flavour in FLAVOURS {
        let plain = legacy_fixtures::plain(&folder(), flavour);
        for kind in ["attributes", "tensors6"] {
            let name = format!("{kind}-{flavour}.vtk");
            let bytes = file(&name);
            let read = parse(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_same(&read, &plain, &name);
        }
    }
}

#[test]
fn a_tensors6_section_of_other_than_six_values_a_node_is_named() {
    for flavour in FLAVOURS {
        let name = format!("tensors6-{flavour}.vtk");
        let bytes = file(&name);
        // Six values more (a node more) in an ASCII file; values of 4 bytes, not 8, in a binary
        // one, which end before the line end VTK writes after them.
        let wrong = if flavour.ends_with("ascii") {
            replaced(
                &bytes,
                b"TENSORS6 strain double\n",
                b"TENSORS6 strain double\n1 2 3 4 5 6\n",
            )
        } else {
            replaced(
                &bytes,
                b"TENSORS6 strain double\n",
                b"TENSORS6 strain float \n",
            )
        };
        let message = parse(&wrong).unwrap_err();
        assert!(message.contains("`TENSORS6 strain"), "{name}: {message}");
        // Cut inside its values.
        let at = legacy_fixtures::position(&bytes, b"TENSORS6 strain double\n") + 40;
        let message = parse(&bytes[..at]).unwrap_err();
        assert!(
            message.contains("TENSORS6 strain double") && message.contains("cut"),
            "{name}: {message}"
        );
    }
}
