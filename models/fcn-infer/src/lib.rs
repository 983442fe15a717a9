//! FCN feasibility evaluator Psi: ONNX inference with tract.
