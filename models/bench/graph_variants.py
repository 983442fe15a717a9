"""Numerically equivalent re-exports of the committed Psi weights, to see which graph form tract
runs fastest (docs/fcn.md, "Architecture and tract"). Not part of training or of the runtime.

    .venv-train/bin/python models/bench/graph_variants.py OUT_DIR
    cargo run --release -p fcn-infer --example compare -- 10 200 OUT_DIR/*.onnx      # tract, round-robin
    .venv-train/bin/python models/bench/graph_variants.py OUT_DIR --ort              # onnxruntime, same files

Variants (each checked against the committed file with onnxruntime, max |diff| ~3e-7):
  v0      the committed graph rebuilt from its initializers
  fold    normalisation folded into enc1's weights, the border correction into pos1 (no Sub/Mul)
  merge   score3+up3 fused into one 1x1 conv, up2 pushed through the first DepthToSpace
  dlast   last 1x1 conv + DepthToSpace as one ConvTranspose 2x2/2, its bias folded into out_bias
  all, all_d, fold_d   combinations
  cat_*   3x3 stride-1 convs as Pad + 9 Slices + Concat + 1x1 conv (explicit im2col)
  batch6/grouped   a fixed batch of 6 folded into channels (every conv grouped 6 ways)
"""
import sys, numpy as np, onnx
from onnx import helper as H, numpy_helper as NH, TensorProto as TP
import onnxruntime as ort

import argparse, time
from pathlib import Path
SRC = str(Path(__file__).resolve().parents[1] / "psi-fcn.onnx")
m = onnx.load(SRC)
W = {i.name: NH.to_array(i).astype(np.float64) for i in m.graph.initializer}

def conv_w(name): return W[name + ".weight"], W[name + ".bias"]

class G:
    def __init__(s, batch="batch"):
        s.nodes, s.inits, s.k = [], [], 0
        s.batch = batch
    def c(s, arr, name=None):
        s.k += 1; name = name or f"c{s.k}"
        s.inits.append(NH.from_array(np.asarray(arr, np.float32), name)); return name
    def n(s, op, ins, **attrs):
        s.k += 1; out = f"t{s.k}"
        s.nodes.append(H.make_node(op, ins, [out], name=f"{op}_{s.k}", **attrs)); return out
    def conv(s, x, w, b=None, pads=(0,0,0,0), stride=1, group=1):
        ins = [x, s.c(w)] + ([s.c(b)] if b is not None else [])
        k = w.shape[2:]
        return s.n("Conv", ins, kernel_shape=list(k), pads=list(pads), strides=[stride, stride], group=group)
    def model(s, out, path, nb=None):
        s.nodes[-1].output[0] = "heatmap"
        for nd in s.nodes:
            for i, x in enumerate(nd.input):
                if x == out: nd.input[i] = "heatmap"
        b = s.batch
        g = H.make_graph(s.nodes, "psi", [H.make_tensor_value_info("crop", TP.UINT8, [b, 1, 32, 64])],
                         [H.make_tensor_value_info("heatmap", TP.FLOAT, [b, 1, 32, 64])], s.inits)
        mm = H.make_model(g, opset_imports=[H.make_opsetid("", 17)], ir_version=8)
        onnx.checker.check_model(mm); onnx.save(mm, path)

def build(path, fold_norm=False, merge_dec=False, deconv_last=False, deconv_all=False):
    g = G()
    mean, inv = float(W["pixel_mean"]), float(W["pixel_inv_std"])
    x = g.n("Cast", ["crop"], to=TP.FLOAT)
    w1, b1 = conv_w("enc1")
    if fold_norm:
        # conv(P((x-m)s)) = s conv(P(x)) - m s conv(P(1)) + b : fold the constant map into pos1
        ones = np.ones((1, 1, 32, 64))
        # conv of padded ones with w1, stride 2 pad 1
        P = np.pad(ones, ((0,0),(0,0),(1,1),(1,1)))
        cm = np.zeros((8, 16, 32))
        for o in range(8):
            for di in range(3):
                for dj in range(3):
                    cm[o] += w1[o, 0, di, dj] * P[0, 0, di:di+32:2, dj:dj+64:2]
        pos = W["pos1"] + b1[None, :, None, None] - mean * inv * cm[None]
        y = g.conv(x, w1 * inv, None, (1,1,1,1), 2)
        f1 = g.n("Relu", [g.n("Add", [y, g.c(pos)])])
    else:
        x = g.n("Mul", [g.n("Sub", [x, g.c(np.float32(mean))]), g.c(np.float32(inv))])
        f1 = g.n("Relu", [g.n("Add", [g.conv(x, w1, b1, (1,1,1,1), 2), g.c(W["pos1"])])])
    f2 = g.n("Relu", [g.conv(f1, *conv_w("enc2"), (1,1,1,1), 2)])
    f2 = g.n("Relu", [g.conv(f2, *conv_w("enc2b"), (1,1,1,1), 1)])
    f3 = g.n("Relu", [g.conv(f2, *conv_w("enc3"), (1,1,1,1), 2)])
    f3 = g.n("Relu", [g.conv(f3, *conv_w("ctx"), (1,1,1,1), 1)])
    m2 = lambda name: (W[name + ".weight"][:, :, 0, 0], W[name + ".bias"])
    Ws3, bs3 = m2("score3"); Wu3, bu3 = m2("up3"); Ws2, bs2 = m2("score2"); Wu2, bu2 = m2("up2")
    Ws1, bs1 = m2("score1"); Wu1, bu1 = m2("up1")
    d2s = lambda t: g.n("DepthToSpace", [t], blocksize=2, mode="CRD")
    c11 = lambda t, Wm, b: g.conv(t, Wm[:, :, None, None], b)
    if not merge_dec:
        s = g.n("Add", [d2s(c11(c11(f3, Ws3, bs3), Wu3, bu3)), c11(f2, Ws2, bs2)])
        s = g.n("Add", [d2s(c11(s, Wu2, bu2)), c11(f1, Ws1, bs1)])
    else:
        A3 = Wu3 @ Ws3; a3 = Wu3 @ bs3 + bu3           # 32 x 32, channel c*4+ij
        C3 = np.zeros((128, 32)); z0 = np.zeros(128)
        for o in range(32):
            for ij in range(4):
                for c in range(8):
                    C3[o*4+ij] += Wu2[o, c] * A3[c*4+ij]
                    z0[o*4+ij] += Wu2[o, c] * a3[c*4+ij]
        B2 = Wu2 @ Ws2; b2 = Wu2 @ bs2 + bu2
        s = g.n("Add", [d2s(c11(f3, C3, z0)), c11(f2, B2, b2)])
        s = g.n("Add", [d2s(s), c11(f1, Ws1, bs1)])
    r = g.n("Relu", [s])
    if deconv_last:
        Wt = np.zeros((8, 1, 2, 2))
        bmap = np.zeros((1, 1, 32, 64))
        for i in range(2):
            for j in range(2):
                Wt[:, 0, i, j] = Wu1[i*2+j]
                bmap[0, 0, i::2, j::2] = bu1[i*2+j]
        o = g.n("ConvTranspose", [r, g.c(Wt)], kernel_shape=[2, 2], strides=[2, 2])
        o = g.n("Add", [o, g.c(W["out_bias"] + bmap)])
    else:
        o = g.n("Add", [d2s(c11(r, Wu1, bu1)), g.c(W["out_bias"])])
    o = g.n("Sigmoid", [o])
    g.model(o, path)

def check(path):
    rng = np.random.default_rng(0)
    x = rng.integers(0, 256, (6, 1, 32, 64), dtype=np.uint8)
    x[0] = 96
    a = ort.InferenceSession(SRC, providers=["CPUExecutionProvider"]).run(None, {"crop": x})[0]
    b = ort.InferenceSession(path, providers=["CPUExecutionProvider"]).run(None, {"crop": x})[0]
    print(path, "max diff", np.abs(a - b).max())



def build_cat(path, layers=("enc2b", "ctx")):
    """3x3 stride-1 convs in `layers` as Pad + 9 Slices + Concat + 1x1 conv."""
    g = G()
    mean, inv = float(W["pixel_mean"]), float(W["pixel_inv_std"])
    x = g.n("Cast", ["crop"], to=TP.FLOAT)
    x = g.n("Mul", [g.n("Sub", [x, g.c(np.float32(mean))]), g.c(np.float32(inv))])
    f1 = g.n("Relu", [g.n("Add", [g.conv(x, *conv_w("enc1"), (1,1,1,1), 2), g.c(W["pos1"])])])
    ints = lambda v: g.c(np.array(v, np.int64)) if False else None
    def c64(v):
        g.k += 1; nm = f"i{g.k}"; g.inits.append(NH.from_array(np.array(v, np.int64), nm)); return nm
    def conv3(t, name, h, w):
        wt, b = conv_w(name)
        if name not in layers:
            return g.conv(t, wt, b, (1,1,1,1), 1)
        p = g.n("Pad", [t, c64([0,0,1,1,0,0,1,1])])
        sl = [g.n("Slice", [p, c64([di, dj]), c64([di + h, dj + w]), c64([2, 3])]) for di in range(3) for dj in range(3)]
        cat = g.n("Concat", sl, axis=1)     # channel index tap*C + c
        co, ci = wt.shape[:2]
        w2 = wt.transpose(0, 2, 3, 1).reshape(co, 9 * ci)
        return g.conv(cat, w2[:, :, None, None], b)
    f2 = g.n("Relu", [g.conv(f1, *conv_w("enc2"), (1,1,1,1), 2)])
    f2 = g.n("Relu", [conv3(f2, "enc2b", 8, 16)])
    f3 = g.n("Relu", [g.conv(f2, *conv_w("enc3"), (1,1,1,1), 2)])
    f3 = g.n("Relu", [conv3(f3, "ctx", 4, 8)])
    m2 = lambda name: (W[name + ".weight"][:, :, 0, 0], W[name + ".bias"])
    d2s = lambda t: g.n("DepthToSpace", [t], blocksize=2, mode="CRD")
    c11 = lambda t, Wm, b: g.conv(t, Wm[:, :, None, None], b)
    s = g.n("Add", [d2s(c11(c11(f3, *m2("score3")), *m2("up3"))), c11(f2, *m2("score2"))])
    s = g.n("Add", [d2s(c11(s, *m2("up2"))), c11(f1, *m2("score1"))])
    o = g.n("Add", [d2s(c11(g.n("Relu", [s]), *m2("up1"))), g.c(W["out_bias"])])
    g.model(g.n("Sigmoid", [o]), path)


def build_grouped(path, B=6):
    """A fixed batch of B crops as one crop of B channels: every conv grouped B ways, weights tiled."""
    g = G(batch=B)
    def c64(v):
        g.k += 1; nm = f"i{g.k}"; g.inits.append(NH.from_array(np.array(v, np.int64), nm)); return nm
    mean, inv = float(W["pixel_mean"]), float(W["pixel_inv_std"])
    x = g.n("Cast", ["crop"], to=TP.FLOAT)
    x = g.n("Reshape", [x, c64([1, B, 32, 64])])
    x = g.n("Mul", [g.n("Sub", [x, g.c(np.float32(mean))]), g.c(np.float32(inv))])
    tw = lambda w: np.concatenate([w] * B, 0)
    gc = lambda t, name, pads, s: g.conv(t, tw(W[name + ".weight"]), tw(W[name + ".bias"]), pads, s, group=B)
    f1 = g.n("Relu", [g.n("Add", [gc(x, "enc1", (1,1,1,1), 2), g.c(np.concatenate([W["pos1"]] * B, 1))])])
    f2 = g.n("Relu", [gc(f1, "enc2", (1,1,1,1), 2)])
    f2 = g.n("Relu", [gc(f2, "enc2b", (1,1,1,1), 1)])
    f3 = g.n("Relu", [gc(f2, "enc3", (1,1,1,1), 2)])
    f3 = g.n("Relu", [gc(f3, "ctx", (1,1,1,1), 1)])
    d2s = lambda t: g.n("DepthToSpace", [t], blocksize=2, mode="CRD")
    c11 = lambda t, name: gc(t, name, (0,0,0,0), 1)
    s = g.n("Add", [d2s(c11(c11(f3, "score3"), "up3")), c11(f2, "score2")])
    s = g.n("Add", [d2s(c11(s, "up2")), c11(f1, "score1")])
    o = g.n("Add", [d2s(c11(g.n("Relu", [s]), "up1")), g.c(np.concatenate([W["out_bias"]] * B, 1))])
    o = g.n("Reshape", [o, c64([B, 1, 32, 64])])
    g.model(g.n("Sigmoid", [o]), path)


def ort_bench(paths, rounds=20, per=200):
    def sess(p):
        o = ort.SessionOptions(); o.intra_op_num_threads = 1; o.inter_op_num_threads = 1
        o.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        o.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        return ort.InferenceSession(str(p), o, providers=["CPUExecutionProvider"])
    ss = [sess(p) for p in paths]
    xs = {b: np.random.default_rng(0).integers(0, 256, (b, 1, 32, 64), dtype=np.uint8) for b in (1, 6)}
    t = {(i, b): [] for i in range(len(ss)) for b in (1, 6)}
    for r in range(rounds):
        for i, s in enumerate(ss):
            for b, n in ((1, per), (6, per // 4)):
                for _ in range(n):
                    t0 = time.perf_counter_ns(); s.run(None, {"crop": xs[b]})
                    if r:
                        t[(i, b)].append((time.perf_counter_ns() - t0) / 1e3)
    for i, p in enumerate(paths):
        print(f"{np.median(t[(i, 1)]):8.1f} {np.median(t[(i, 6)]):8.1f}  {p}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", type=Path)
    ap.add_argument("--ort", action="store_true", help="time the variants in OUT with onnxruntime instead")
    a = ap.parse_args()
    if a.ort:
        ort_bench(sorted(a.out.glob("*.onnx")))
    else:
        a.out.mkdir(parents=True, exist_ok=True)
        variants = {
            "v0": {}, "fold": dict(fold_norm=True), "merge": dict(merge_dec=True),
            "dlast": dict(deconv_last=True), "all": dict(fold_norm=True, merge_dec=True),
            "all_d": dict(fold_norm=True, merge_dec=True, deconv_last=True),
            "fold_d": dict(fold_norm=True, deconv_last=True),
        }
        for k, v in variants.items():
            p = str(a.out / f"{k}.onnx"); build(p, **v); check(p)
        for k, layers in {"cat_both": ("enc2b", "ctx"), "cat_b": ("enc2b",), "cat_ctx": ("ctx",)}.items():
            p = str(a.out / f"{k}.onnx"); build_cat(p, layers); check(p)
        # Fixed batch of 6 only: `cargo run --release -p fcn-infer --example profile_ops -- OUT/batch6/grouped.onnx 6`
        (a.out / "batch6").mkdir(exist_ok=True)
        p = str(a.out / "batch6" / "grouped.onnx"); build_grouped(p); check(p)
