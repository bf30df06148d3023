//! The crate's integration tests in one binary: one link instead of one per file (the build
//! time that matters on 2 cores). Each file is a module, named as the file.

mod adaptive_detection;
mod bad_input;
mod common;
mod csv_files;
mod lattice_detection;
mod legacy_dataset_field;
mod legacy_id_sections;
mod legacy_string_arrays;
mod lzma_hostile;
mod messages;
mod node_sources;
mod other_data_sets;
mod parallel_files;
mod parser_property;
mod regression_appended_array_without_offset;
mod regression_appended_counts_unchecked;
mod regression_block_of_the_wrong_size;
mod regression_corrupt_block_header_aborted;
mod regression_corrupt_displacement_dropped;
mod regression_float_hanging_nodes_lost_owners;
mod regression_float_points_off_the_lattice;
mod regression_legacy_counts_blamed_line_1;
mod regression_legacy_cut_inside_last_value;
mod regression_legacy_names_percent_encoded;
mod regression_legacy_point_data_count_parsed;
mod regression_many_appended_arrays_quadratic;
mod regression_many_pieces_quadratic;
mod regression_printed_coordinates_refused;
mod regression_xml_errors_named_no_array;
mod regression_xml_faults_unnamed_in_any_encoding;
mod regression_xml_spellings_bypassed_the_guard;
mod several_pieces;
mod vtk_round_trip;
mod written_by_vtk;
mod written_by_vtk_adaptive;
