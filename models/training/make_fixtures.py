"""Write the small ONNX fixtures of models/fcn-infer/tests/fixtures (committed; rerun to refresh).

    python models/training/make_fixtures.py

- scale.onnx:        the right interface, heatmap = crop / 255 (checks batching and copying exactly)
- wrong_shape.onnx:  expects 64 x 64 crops
- wrong_output.onnx: right input, but one value per crop instead of a heatmap
- float_input.onnx:  float32 input instead of uint8
- corrupt.onnx:      scale.onnx cut in half
"""

from pathlib import Path

import onnx
from onnx import TensorProto, helper

OUT = Path(__file__).resolve().parents[1] / "fcn-infer" / "tests" / "fixtures"


def model(name, in_type, in_shape, out_shape, nodes, inits=()):
    graph = helper.make_graph(
        nodes, name,
        [helper.make_tensor_value_info("crop", in_type, in_shape)],
        [helper.make_tensor_value_info("heatmap", TensorProto.FLOAT, out_shape)],
        initializer=list(inits))
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="grop-fixtures",
                          ir_version=8)
    onnx.checker.check_model(m)
    return m


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    scale = helper.make_tensor("inv255", TensorProto.FLOAT, [], [1.0 / 255.0])
    cast = helper.make_node("Cast", ["crop"], ["x"], to=TensorProto.FLOAT)
    mul = helper.make_node("Mul", ["x", "inv255"], ["heatmap"])
    ok = model("scale", TensorProto.UINT8, ["N", 1, 32, 64], ["N", 1, 32, 64], [cast, mul], [scale])
    onnx.save(ok, OUT / "scale.onnx")
    onnx.save(model("wrong_shape", TensorProto.UINT8, ["N", 1, 64, 64], ["N", 1, 64, 64], [cast, mul], [scale]),
              OUT / "wrong_shape.onnx")
    red = helper.make_node("ReduceMean", ["x"], ["m"], axes=[2, 3], keepdims=1)
    mul2 = helper.make_node("Mul", ["m", "inv255"], ["heatmap"])
    onnx.save(model("wrong_output", TensorProto.UINT8, ["N", 1, 32, 64], ["N", 1, 1, 1], [cast, red, mul2], [scale]),
              OUT / "wrong_output.onnx")
    sig = helper.make_node("Sigmoid", ["crop"], ["heatmap"])
    onnx.save(model("float_input", TensorProto.FLOAT, ["N", 1, 32, 64], ["N", 1, 32, 64], [sig]),
              OUT / "float_input.onnx")
    raw = (OUT / "scale.onnx").read_bytes()
    (OUT / "corrupt.onnx").write_bytes(raw[: len(raw) // 2])
    print(f"wrote fixtures to {OUT}")


if __name__ == "__main__":
    main()
