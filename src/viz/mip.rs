//! Maximum-intensity projections of an NLOS reconstruction (`tstat nlos mip`): the
//! volume V (NX, NY, NZ) projected along one axis,
//!
//! ```text
//!   z: P(x, y) = max_z V(x, y, z)   (the view from the relay wall: x right, y up)
//!   x: P(z, y) = max_x V(x, y, z)   (from the side: depth right, y up)
//!   y: P(x, z) = max_y V(x, y, z)   (from above: x right, depth up)
//! ```
//!
//! scaled by the projection's maximum and coloured with a perceptual ramp (black, purple,
//! orange, yellow-white; after matplotlib's `inferno`), each cell drawn as a square of
//! pixels so that small volumes stay legible.

/// The projection axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
}

/// A projection: `width x height` values, row 0 at the top.
pub struct MipImage {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
}

/// The projection of `v` ((NX, NY, NZ) row-major) along `axis`; NaN cells count as 0.
pub fn project(v: &[f32], n: [usize; 3], axis: Axis) -> MipImage {
    assert_eq!(v.len(), n[0] * n[1] * n[2], "volume of {n:?} voxels");
    let mut p = Projector::new(n, axis);
    p.add(0, v);
    p.finish()
}

/// A projection built while the volume is read, a band of x slices at a time (the
/// volume is never held whole): memory is the projection's cells.
pub struct Projector {
    n: [usize; 3],
    axis: Axis,
    p: MipImage,
}

impl Projector {
    pub fn new(n: [usize; 3], axis: Axis) -> Projector {
        let [nx, ny, nz] = n;
        let (width, height) = match axis {
            Axis::Z => (nx, ny),
            Axis::X => (nz, ny),
            Axis::Y => (nx, nz),
        };
        Projector {
            n,
            axis,
            p: MipImage {
                width,
                height,
                values: vec![f32::NEG_INFINITY; width * height],
            },
        }
    }

    /// The projection's (width, height).
    pub fn size(&self) -> (usize, usize) {
        (self.p.width, self.p.height)
    }

    /// Adds x slices `x0..` given as `band` (whole (NY, NZ) slices, row-major); NaN
    /// cells count as 0.
    pub fn add(&mut self, x0: usize, band: &[f32]) {
        let [_, ny, nz] = self.n;
        let slice = ny * nz;
        assert!(
            slice > 0 && band.len().is_multiple_of(slice),
            "whole x slices"
        );
        let (w, h) = (self.p.width, self.p.height);
        let values = &mut self.p.values;
        let zero_nan = |x: f32| if x.is_nan() { 0.0 } else { x };
        for (di, s) in band.chunks_exact(slice).enumerate() {
            let i = x0 + di;
            // Voxel (i, j, k) lands on one cell; row 0 of the projection at the top.
            for (j, line) in s.chunks_exact(nz).enumerate() {
                match self.axis {
                    Axis::Z => {
                        let m = line
                            .iter()
                            .fold(f32::NEG_INFINITY, |a, &x| a.max(zero_nan(x)));
                        let cell = &mut values[(h - 1 - j) * w + i];
                        *cell = cell.max(m);
                    }
                    Axis::X => {
                        let row = &mut values[(h - 1 - j) * w..(h - j) * w];
                        for (cell, &x) in row.iter_mut().zip(line) {
                            *cell = cell.max(zero_nan(x));
                        }
                    }
                    Axis::Y => {
                        for (k, &x) in line.iter().enumerate() {
                            let cell = &mut values[(h - 1 - k) * w + i];
                            *cell = cell.max(zero_nan(x));
                        }
                    }
                }
            }
        }
    }

    pub fn finish(self) -> MipImage {
        self.p
    }
}

/// The colour ramp at `t` in [0, 1].
pub fn ramp(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.0, 0.0, 4.0],
        [87.0, 16.0, 110.0],
        [188.0, 55.0, 84.0],
        [249.0, 142.0, 9.0],
        [252.0, 255.0, 164.0],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (STOPS.len() - 1) as f32;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f32;
    [0, 1, 2].map(|c| (STOPS[i][c] + f * (STOPS[i + 1][c] - STOPS[i][c])).round() as u8)
}

/// The projection as RGB8 pixels, `scale` pixels per cell, scaled by its maximum (an
/// all-zero projection is black); returns (width, height, pixels).
pub fn picture(p: &MipImage, scale: usize) -> (u32, u32, Vec<u8>) {
    let top = p.values.iter().fold(0f32, |a, &b| a.max(b));
    let (w, h) = (p.width * scale, p.height * scale);
    let mut px = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let v = p.values[(y / scale) * p.width + x / scale];
            let t = if top > 0.0 { v.max(0.0) / top } else { 0.0 };
            px.extend_from_slice(&ramp(t));
        }
    }
    (w as u32, h as u32, px)
}
/// Pictures of one height side by side, left to right, `gap` grey columns between
/// them; returns (width, height, pixels).
pub fn side_by_side(pictures: &[(u32, u32, Vec<u8>)], gap: u32) -> (u32, u32, Vec<u8>) {
    let h = pictures.first().map_or(0, |p| p.1);
    assert!(pictures.iter().all(|p| p.1 == h), "pictures of one height");
    let n = pictures.len() as u32;
    let w = pictures.iter().map(|p| p.0).sum::<u32>() + gap * n.saturating_sub(1);
    let mut px = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h as usize {
        for (k, (pw, _, p)) in pictures.iter().enumerate() {
            if k > 0 {
                px.extend(std::iter::repeat_n(96u8, 3 * gap as usize));
            }
            let row = *pw as usize * 3;
            px.extend_from_slice(&p[y * row..(y + 1) * row]);
        }
    }
    (w, h, px)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition, one projected cell at a time.
    fn reference(v: &[f32], n: [usize; 3], axis: Axis) -> Vec<f32> {
        let [nx, ny, nz] = n;
        let at = |i: usize, j: usize, k: usize| {
            let x = v[(i * ny + j) * nz + k];
            if x.is_nan() {
                0.0
            } else {
                x
            }
        };
        let (width, height) = match axis {
            Axis::Z => (nx, ny),
            Axis::X => (nz, ny),
            Axis::Y => (nx, nz),
        };
        let mut out = Vec::new();
        for r in 0..height {
            let up = height - 1 - r;
            for c in 0..width {
                out.push(match axis {
                    Axis::Z => (0..nz)
                        .map(|k| at(c, up, k))
                        .fold(f32::NEG_INFINITY, f32::max),
                    Axis::X => (0..nx)
                        .map(|i| at(i, up, c))
                        .fold(f32::NEG_INFINITY, f32::max),
                    Axis::Y => (0..ny)
                        .map(|j| at(c, j, up))
                        .fold(f32::NEG_INFINITY, f32::max),
                });
            }
        }
        out
    }

    #[test]
    fn projections_in_bands_equal_the_definition() {
        let n = [5, 4, 3];
        let mut state = 7u64;
        let v: Vec<f32> = (0..60)
            .map(|i| {
                state = crate::math::rng::mix64(state ^ i);
                if i == 17 {
                    f32::NAN
                } else {
                    (state >> 40) as f32 / (1u64 << 24) as f32 - 0.3
                }
            })
            .collect();
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let want = reference(&v, n, axis);
            assert_eq!(project(&v, n, axis).values, want, "{axis:?}");
            // Bands of 2, 2 and 1 x slices.
            let mut p = Projector::new(n, axis);
            for (x0, x1) in [(0, 2), (2, 4), (4, 5)] {
                p.add(x0, &v[x0 * 12..x1 * 12]);
            }
            let p = p.finish();
            assert_eq!(p.values, want, "{axis:?} in bands");
            assert_eq!(p.width * p.height, want.len());
        }
        // The picture is the projection's orientation: voxel (4, 0, 0) alone lit is the
        // bottom-right cell of the view along z.
        let mut one = vec![0f32; 60];
        one[4 * 12] = 1.0;
        let p = project(&one, n, Axis::Z);
        assert_eq!(p.values[(p.height - 1) * p.width + 4], 1.0);
        assert_eq!(p.values.iter().filter(|&&x| x == 1.0).count(), 1);
    }

    #[test]
    fn side_by_side_puts_each_picture_in_its_columns() {
        // A 2 x 2 red picture and a 1 x 2 blue one, one grey column between.
        let red = (2, 2, [255, 0, 0].repeat(4));
        let blue = (1, 2, [0, 0, 255].repeat(2));
        let (w, h, px) = side_by_side(&[red, blue], 1);
        assert_eq!((w, h), (4, 2));
        let row = [[255, 0, 0], [255, 0, 0], [96, 96, 96], [0, 0, 255]].concat();
        assert_eq!(px, [row.clone(), row].concat());
    }
}
