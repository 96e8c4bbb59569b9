#!/usr/bin/env python3
"""Makes the JPEG fixtures of tests/it/jpeg.rs: small JPEGs in each mode tstat reads,
and beside each the samples libjpeg decodes for it (raw 8-bit, rows from the top,
3 bytes a pixel for colour, 1 for grey), as `NAME.jpg` + `NAME.raw`.

The decodes come from Pillow, which links libjpeg-turbo and decodes with libjpeg's
defaults (JDCT_ISLOW, do_fancy_upsampling = TRUE) unless `Image.draft` is called,
which this script never does. Made with Pillow 13.0.0 on libjpeg-turbo 3.2.0 (the
versions are printed; the script refuses a Pillow without libjpeg-turbo).

Needs only Pillow (`pip install pillow`); run from the repository root:
    python3 scripts/make_jpeg_fixtures.py
Nothing in `cargo test` runs Python: the outputs are committed.
"""
import io
import os
import random

from PIL import Image, features

OUT = os.path.join("tests", "data", "jpeg")


def picture(w, h, seed):
    """Colour gradients with noise and a few hard edges, so chroma varies at every
    scale the upsampler sees."""
    rnd = random.Random(seed)
    img = Image.new("RGB", (w, h))
    px = img.load()
    for y in range(h):
        for x in range(w):
            r = int(255 * x / max(w - 1, 1))
            g = int(255 * y / max(h - 1, 1))
            b = 255 if (x // 5 + y // 3) % 2 else 40
            n = rnd.randint(-30, 30)
            px[x, y] = (
                max(0, min(255, r + n)),
                max(0, min(255, g - n)),
                max(0, min(255, b + n // 2)),
            )
    return img


# name, size, mode, save options
CASES = [
    ("baseline_420", (33, 17), "RGB", dict(quality=85, subsampling="4:2:0")),
    ("baseline_422", (31, 19), "RGB", dict(quality=85, subsampling="4:2:2")),
    ("baseline_444", (17, 16), "RGB", dict(quality=85, subsampling="4:4:4")),
    ("progressive_420", (23, 21), "RGB", dict(quality=80, subsampling="4:2:0", progressive=True)),
    ("restart_420", (40, 24), "RGB", dict(quality=90, subsampling="4:2:0", restart_marker_blocks=3)),
    ("narrow_420", (3, 9), "RGB", dict(quality=85, subsampling="4:2:0")),
    ("grey", (19, 13), "L", dict(quality=85)),
    ("grey_progressive", (18, 15), "L", dict(quality=85, progressive=True)),
    ("rgb_adobe", (16, 16), "RGB", dict(quality=90, keep_rgb=True)),
]


def main():
    if not features.check_feature("libjpeg_turbo"):
        raise SystemExit("Pillow is not built with libjpeg-turbo")
    print("Pillow", Image.__version__, "libjpeg-turbo", features.version("libjpeg_turbo"))
    os.makedirs(OUT, exist_ok=True)
    for i, (name, size, mode, opts) in enumerate(CASES):
        img = picture(*size, seed=i)
        if mode == "L":
            img = img.convert("L")
        buf = io.BytesIO()
        img.save(buf, "JPEG", **opts)
        data = buf.getvalue()
        with open(os.path.join(OUT, name + ".jpg"), "wb") as f:
            f.write(data)
        dec = Image.open(io.BytesIO(data))  # no draft(): libjpeg's defaults
        dec.load()
        assert dec.mode == mode, (name, dec.mode)
        with open(os.path.join(OUT, name + ".raw"), "wb") as f:
            f.write(dec.tobytes())
        print(name, dec.size, dec.mode, len(data), "bytes")
    # CMYK: refused by tstat as by Mitsuba; no decode kept.
    img = picture(8, 8, seed=99).convert("CMYK")
    img.save(os.path.join(OUT, "cmyk.jpg"), "JPEG", quality=85)


if __name__ == "__main__":
    main()
