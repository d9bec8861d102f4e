#!/usr/bin/env python3
"""Compares view.html's picture with `pixelflow-sim render`'s: 8-bit sRGB RGB pixels as stored.

    python3 compare.py THREE.png REFERENCE.png [DIFF.png]

Prints the PSNR over all pixels and channels (peak 255), the mean absolute and mean signed
difference per channel (three minus reference, in 8-bit steps), the largest difference, how
many pixels differ by more than 1, 2, 5, 10, 20 and 50 steps, and where: on edges (pixels
within 1 pixel of a step of more than 24 steps between neighbours in the reference), on the
lamp (within 2 pixels of the reference's saturated white), or elsewhere (smooth interior), with
the PSNR of each class. With DIFF.png, writes the largest channel difference per pixel times 8
as a grey image. Needs numpy and Pillow.
"""

import sys

import numpy as np
from PIL import Image


def dilate(mask, r):
    out = mask.copy()
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out |= np.roll(np.roll(mask, dy, axis=0), dx, axis=1)
    return out


def psnr(d):
    mse = float((d ** 2).mean()) if d.size else 0.0
    return float("inf") if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    a_img, b_img = Image.open(sys.argv[1]), Image.open(sys.argv[2])
    if a_img.mode == "RGBA":
        alpha = np.asarray(a_img)[..., 3]
        print(f"alpha of {sys.argv[1]}: min {alpha.min()} max {alpha.max()} (ignored)")
    a = np.asarray(a_img.convert("RGB")).astype(np.float64)
    b = np.asarray(b_img.convert("RGB")).astype(np.float64)
    if a.shape != b.shape:
        sys.exit(f"sizes differ: {a.shape[1]}x{a.shape[0]} and {b.shape[1]}x{b.shape[0]}")
    h, w, _ = a.shape
    d = a - b
    ad = np.abs(d)
    m = ad.max(axis=2)

    # Edges: a step of more than 24 between a reference pixel and any 8-neighbour.
    step = np.zeros((h, w), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                nb = np.roll(np.roll(b, dy, axis=0), dx, axis=1)
                step |= np.abs(b - nb).max(axis=2) > 24
    step[0, :] = step[-1, :] = step[:, 0] = step[:, -1] = False  # np.roll wraps around
    edge = dilate(step, 1)
    lamp = dilate((b == 255).all(axis=2), 2)
    classes = {"lamp": lamp, "edge": edge & ~lamp, "interior": ~edge & ~lamp}

    print(f"{w}x{h} pixels")
    print(f"PSNR (all pixels, RGB, peak 255): {psnr(d):.2f} dB")
    print("mean |three - reference| per channel R G B: " + " ".join(f"{x:.4f}" for x in ad.mean(axis=(0, 1))))
    print("mean (three - reference) per channel R G B: " + " ".join(f"{x:+.4f}" for x in d.mean(axis=(0, 1))))
    print(f"identical pixels: {(m == 0).sum()} of {h * w} ({100 * (m == 0).mean():.2f} %)")
    iy, ix = np.unravel_index(np.argmax(m), m.shape)
    print(f"largest difference: {int(m.max())} steps at x={ix}, y={iy} "
          f"(three {a[iy, ix].astype(int).tolist()}, reference {b[iy, ix].astype(int).tolist()})")
    ts = (1, 2, 5, 10, 20, 50)
    print("class       pixels  PSNR dB   " + "  ".join(f">{t:<4}" for t in ts))
    for name, mask in classes.items():
        counts = "  ".join(f"{int((m[mask] > t).sum()):<5}" for t in ts)
        print(f"{name:<10} {int(mask.sum()):>7}  {psnr(d[mask]):7.2f}   {counts}")
    if len(sys.argv) > 3:
        Image.fromarray(np.clip(m * 8, 0, 255).astype(np.uint8)).save(sys.argv[3])
        print(f"wrote {sys.argv[3]}")


if __name__ == "__main__":
    main()
