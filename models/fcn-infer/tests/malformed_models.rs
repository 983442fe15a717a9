//! Malformed model bytes are load errors, never panics (a model file is outside input; these
//! cases were found by fuzzing, docs/fuzzing.md).

use std::path::Path;

use fcn_infer::{FcnModel, ModelLoadError};

#[test]
fn a_graph_output_that_names_no_node_is_corrupt_not_a_panic() {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/float_input.onnx");
    let mut bytes = std::fs::read(fixture).unwrap();
    // The fixture's graph output is "heatmap", the Sigmoid node's output. Rename the graph
    // output alone (its last mention), keeping every protobuf length: tract's importer then
    // looked the name up with an index that panicked.
    let at = bytes.windows(7).rposition(|w| w == b"heatmap").unwrap();
    bytes[at..at + 7].copy_from_slice(b"heaptam");
    match FcnModel::from_bytes(&bytes, Path::new("dangling-output.onnx")) {
        Err(ModelLoadError::Corrupt { path, reason }) => {
            assert_eq!(path, Path::new("dangling-output.onnx"));
            assert!(reason.contains("ONNX importer"), "{reason}");
        }
        other => panic!("expected a corrupt-model error, got {other:?}"),
    }
    // The unmodified fixture still reaches the interface check (float input): the guard
    // changes nothing for models tract reads.
    let good = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/float_input.onnx"),
    )
    .unwrap();
    assert!(matches!(
        FcnModel::from_bytes(&good, Path::new("float_input.onnx")),
        Err(ModelLoadError::WrongInterface { .. })
    ));
}
