"""The Psi network: a small FCN-8s-style fully convolutional net for 64 x 32 near-side crops.

Input:  uint8 crop [N, 1, 32, 64], exactly the grayscale crop `world::view::render_crop` returns
        (far-side crops are already rotated 180 degrees so they look like near crops).
Output: float32 heatmap [N, 1, 32, 64] in [0, 1]: per cell, the probability that a base commanded
        there (facing the table) ends collision-free and can place the object (paper eq. 2-3).

Why this shape (see docs/fcn.md for the measurements):
- The paper used FCN-8s on VGG; at 64 x 32 px that is three orders of magnitude more compute than
  the problem needs. We keep FCN-8s' structure: a strided encoder (strides 2, 4, 8), per-stride
  1x1 "score" layers, learned 2x up-sampling fused by addition with the skip scores, down to full
  resolution. The up-sampling is sub-pixel convolution (1x1 conv + DepthToSpace) rather than
  transposed convolution: measured in tract, ConvTranspose and Resize cost more than the whole
  encoder (docs/fcn.md).
- Strided 3x3 convolutions instead of conv + max-pool: the same receptive field for a fraction of
  the FLOPs, and tract runs them as one im2col + matmul each.
- Reachability depends on where a cell lies relative to the target, which sits at a fixed place
  in every crop, but a convolution is translation-equivariant. Two learned position-bias maps (one
  on the stride-2 features, one on the output logits) give the network that absolute position,
  like CoordConv but free at inference: a broadcast add.
- Normalisation of the uint8 input happens inside the graph, with the training set's mean and
  standard deviation baked in as constants, so the Rust side feeds raw crops.
"""

from __future__ import annotations

import torch
from torch import nn

CROP_ROWS = 32
CROP_COLS = 64


class PsiFcn(nn.Module):
    """FCN-8s-style feasibility evaluator sized for 64 x 32 crops (widths c1, c2, c3; k score channels)."""

    def __init__(self, c1: int = 8, c2: int = 16, c3: int = 32, k: int = 8, up1_kernel: int = 1,
                 pixel_mean: float = 128.0, pixel_std: float = 64.0):
        super().__init__()
        self.widths = (c1, c2, c3, k, up1_kernel)
        self.register_buffer("pixel_mean", torch.tensor(float(pixel_mean)))
        self.register_buffer("pixel_inv_std", torch.tensor(1.0 / float(pixel_std)))
        # Encoder: stride 2, 4, 8 (16x32, 8x16, 4x8 feature maps).
        self.enc1 = nn.Conv2d(1, c1, 3, stride=2, padding=1)
        self.pos1 = nn.Parameter(torch.zeros(1, c1, CROP_ROWS // 2, CROP_COLS // 2))
        self.enc2 = nn.Conv2d(c1, c2, 3, stride=2, padding=1)
        self.enc2b = nn.Conv2d(c2, c2, 3, padding=1)
        self.enc3 = nn.Conv2d(c2, c3, 3, stride=2, padding=1)
        # Context at stride 8: the 3x3 on a 4x8 map sees the whole crop.
        self.ctx = nn.Conv2d(c3, c3, 3, padding=1)
        # FCN-8s scores per stride, fused coarse-to-fine. Up-sampling is sub-pixel (1x1 conv to
        # 4x the channels, then DepthToSpace): learned like FCN's deconvolutions, but tract runs
        # ConvTranspose and Resize 3-5x slower than a 1x1 conv plus an axis move (docs/fcn.md).
        self.score3 = nn.Conv2d(c3, k, 1)
        self.score2 = nn.Conv2d(c2, k, 1)
        self.score1 = nn.Conv2d(c1, k, 1)
        self.up3 = nn.Conv2d(k, 4 * k, 1)
        self.up2 = nn.Conv2d(k, 4 * k, 1)
        self.up1 = nn.Conv2d(k, 4, up1_kernel, padding=up1_kernel // 2)
        self.shuffle = nn.PixelShuffle(2)
        self.out_bias = nn.Parameter(torch.zeros(1, 1, CROP_ROWS, CROP_COLS))
        self.act = nn.ReLU()

    def logits(self, crop_u8: torch.Tensor) -> torch.Tensor:
        x = (crop_u8.to(torch.float32) - self.pixel_mean) * self.pixel_inv_std
        f1 = self.act(self.enc1(x) + self.pos1)          # stride 2, 16 x 32
        f2 = self.act(self.enc2(f1))                     # stride 4, 8 x 16
        f2 = self.act(self.enc2b(f2))
        f3 = self.act(self.enc3(f2))                     # stride 8, 4 x 8
        f3 = self.act(self.ctx(f3))
        s = self.shuffle(self.up3(self.score3(f3))) + self.score2(f2)
        s = self.shuffle(self.up2(s)) + self.score1(f1)
        s = self.shuffle(self.up1(self.act(s)))          # full resolution, 32 x 64
        return s + self.out_bias

    def forward(self, crop_u8: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(self.logits(crop_u8))


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def count_macs(model: PsiFcn) -> int:
    """Multiply-accumulates of one crop, counted per layer from the actual output shapes."""
    macs = 0
    hooks = []

    def conv_hook(mod, inp, out):
        nonlocal macs
        if isinstance(mod, nn.ConvTranspose2d):
            # Each input element scatters into kh*kw outputs per output channel.
            n_in = inp[0].numel() // inp[0].shape[0]
            macs += n_in * mod.out_channels * mod.kernel_size[0] * mod.kernel_size[1]
        else:
            n_out = out.numel() // out.shape[0]
            macs += n_out * (mod.in_channels // mod.groups) * mod.kernel_size[0] * mod.kernel_size[1]

    for m in model.modules():
        if isinstance(m, (nn.Conv2d, nn.ConvTranspose2d)):
            hooks.append(m.register_forward_hook(conv_hook))
    with torch.no_grad():
        model(torch.zeros(1, 1, CROP_ROWS, CROP_COLS, dtype=torch.uint8))
    for h in hooks:
        h.remove()
    return macs
