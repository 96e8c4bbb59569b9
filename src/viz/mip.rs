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
pub struct Projection {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
}

/// The projection of `v` ((NX, NY, NZ) row-major) along `axis`; NaN cells count as 0.
pub fn project(v: &[f32], n: [usize; 3], axis: Axis) -> Projection {
    let [nx, ny, nz] = n;
    assert_eq!(v.len(), nx * ny * nz, "volume of {n:?} voxels");
    let at = |i: usize, j: usize, k: usize| {
        let x = v[(i * ny + j) * nz + k];
        if x.is_nan() {
            0.0
        } else {
            x
        }
    };
    // (width, height, cell of image column c and row r -> the ray's voxels)
    let (width, height) = match axis {
        Axis::Z => (nx, ny),
        Axis::X => (nz, ny),
        Axis::Y => (nx, nz),
    };
    let mut values = vec![f32::NEG_INFINITY; width * height];
    for r in 0..height {
        let up = height - 1 - r;
        for c in 0..width {
            let m = match axis {
                Axis::Z => (0..nz)
                    .map(|k| at(c, up, k))
                    .fold(f32::NEG_INFINITY, f32::max),
                Axis::X => (0..nx)
                    .map(|i| at(i, up, c))
                    .fold(f32::NEG_INFINITY, f32::max),
                Axis::Y => (0..ny)
                    .map(|j| at(c, j, up))
                    .fold(f32::NEG_INFINITY, f32::max),
            };
            values[r * width + c] = m;
        }
    }
    Projection {
        width,
        height,
        values,
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
pub fn picture(p: &Projection, scale: usize) -> (u32, u32, Vec<u8>) {
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
    use super::side_by_side;

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
