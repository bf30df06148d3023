//! Regression: VTK's legacy writer stores an array named `my displacement` as
//! `my%20displacement` and its reader decodes it; we compared the encoded name, so
//! `--displacement "my displacement"` found no array ("point arrays found: my%20displacement").

use cgcontact_io::{DisplacementArray, parse_hex_mesh};

use crate::common::{self, LegacyData, legacy_ascii};

#[test]
fn legacy_array_names_are_percent_decoded_as_vtk_reads_them() {
    let mesh = common::displaced_mesh(7);
    for data in [LegacyData::Vectors, LegacyData::Field] {
        let text = legacy_ascii(&mesh, data, false);
        let encoded = text.replacen("displacement", "my%20displacement", 1);
        assert_ne!(encoded, text);
        let named = DisplacementArray::Named("my displacement".to_owned());
        let read = parse_hex_mesh(encoded.as_bytes(), &named).unwrap();
        assert_eq!(read.displacement, mesh.displacement);
        // The names listed in an error are decoded too.
        let other = DisplacementArray::Named("other".to_owned());
        let message = parse_hex_mesh(encoded.as_bytes(), &other)
            .unwrap_err()
            .to_string();
        assert!(message.contains("found: my displacement"), "{message}");
    }
}
