#!/usr/bin/env python3
"""Writes the small y-tal HDF5 captures under tests/data/tal/ with real h5py, the way
y-tal's `tal.io.write_capture` lays them out (H T_Sx_Sy, grids X_Y_3, scalars), in
the storage layouts h5py offers: contiguous, chunked, gzip, gzip + shuffle,
gzip + shuffle + fletcher32. Every file holds the same values; tests/it/hostile_tal.rs
and tests/it/fuzz_tal.rs read them.

    python3 -m venv /tmp/h5 && /tmp/h5/bin/pip install h5py numpy
    /tmp/h5/bin/python scripts/make_tal_fixtures.py

The capture: a confocal 4 x 4 scan of 16 bins of a point at (0.1, -0.2, 0.6) behind a
wall z = 0 of 0.5 x 0.5 (H: a peak of the point's round trip per sensor point, plus a
deterministic pattern, so that compression has something to do).
"""

import os
import sys

import h5py
import numpy as np

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "data", "tal")

T, SX, SY = 16, 4, 4
DELTA_T = 0.1
T_START = 0.6


def capture():
    xs = np.linspace(-0.25, 0.25, SX)
    ys = np.linspace(-0.25, 0.25, SY)
    grid = np.zeros((SX, SY, 3), np.float32)
    grid[..., 0] = xs[:, None]
    grid[..., 1] = ys[None, :]
    normals = np.zeros((SX, SY, 3), np.float32)
    normals[..., 2] = 1.0
    hidden = np.array([0.1, -0.2, 0.6])
    h = np.zeros((T, SX, SY), np.float32)
    for i in range(SX):
        for j in range(SY):
            d = 2.0 * np.linalg.norm(grid[i, j] - hidden)
            b = int((d - T_START) / DELTA_T)
            if 0 <= b < T:
                h[b, i, j] = 1.0 / (d * d)
    # A deterministic small background, so that every value is distinct.
    h += (np.arange(T * SX * SY, dtype=np.float32).reshape(T, SX, SY) % 7) * np.float32(1e-3)
    return h, grid, normals


def write(name, **h_options):
    h, grid, normals = capture()
    path = os.path.join(OUT, name)
    with h5py.File(path, "w") as f:
        f.create_dataset("H", data=h, **h_options)
        f.create_dataset("H_format", data=np.int32(1))
        f.create_dataset("sensor_grid_xyz", data=grid)
        f.create_dataset("sensor_grid_normals", data=normals)
        f.create_dataset("sensor_grid_format", data=np.int32(2))
        f.create_dataset("laser_grid_xyz", data=grid)
        f.create_dataset("laser_grid_normals", data=normals)
        f.create_dataset("laser_grid_format", data=np.int32(2))
        f.create_dataset("sensor_xyz", data=np.array([0.0, 0.0, 1.0], np.float32))
        f.create_dataset("laser_xyz", data=np.array([0.0, 0.0, 1.0], np.float32))
        f.create_dataset("delta_t", data=np.float64(DELTA_T))
        f.create_dataset("t_start", data=np.float64(T_START))
        f.create_dataset("t_accounts_first_and_last_bounces", data=np.bool_(False))
        f.create_dataset("scene_info", data="{'fixture': 'scripts/make_tal_fixtures.py'}")
    print(f"{path}: {os.path.getsize(path)} bytes", file=sys.stderr)


def main():
    os.makedirs(OUT, exist_ok=True)
    write("contiguous.hdf5")
    write("chunked.hdf5", chunks=(4, 2, 2))
    write("gzip.hdf5", compression="gzip", compression_opts=4)
    write("gzip_shuffle.hdf5", compression="gzip", shuffle=True, chunks=(8, 4, 2))
    write("gzip_shuffle_fletcher32.hdf5", compression="gzip", shuffle=True, fletcher32=True)
    # The values, for the tests: little-endian f32, (T, Sx, Sy) row-major.
    h, _, _ = capture()
    h.astype("<f4").tofile(os.path.join(OUT, "h_values.f32"))


if __name__ == "__main__":
    main()
