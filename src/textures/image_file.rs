//! Decoding image files for `bitmap` textures into linear f32 texels: PNG (8/16-bit,
//! sRGB-encoded), BMP and Radiance HDR (linear) through the `image` crate; JPEG
//! (sRGB-encoded) through [`crate::textures::jpeg`], which decodes as libjpeg (and so
//! Mitsuba) does; OpenEXR (linear) through the `exr` crate.
//!
//! Hostile files end in an error, never a panic nor an unbounded allocation: the file
//! is read through `io::read_regular` (regular files of bounded size), the dimensions
//! are read from the header and checked against [`MAX_TEXELS`] before any pixel is
//! decoded, and the decoders run under an allocation limit.

use crate::io::{read_regular, MAX_IMAGE_BYTES};
use std::io::Cursor;
use std::path::Path;

/// The most texels an image may have (16k x 16k): 3 GiB of f32 RGB.
pub const MAX_TEXELS: u64 = 1 << 28;
/// What a decoder may allocate for one image.
const MAX_DECODE_ALLOC: u64 = 4 << 30;

/// Decoded texels, row-major from the first stored row, 1 or 3 channels.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageData {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: Vec<f32>,
}

/// The sRGB transfer function's inverse (IEC 61966-2-1), as Dr.Jit's `srgb_to_linear`.
#[inline]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Why an image file cannot be a texture. The message is a short reason without the
/// path (the caller names the file), e.g. "is not a PNG, JPEG, ... image".
#[derive(Debug, thiserror::Error)]
pub enum ImageFileError {
    /// The file could not be read (missing, not a regular file, too large, ...).
    #[error(transparent)]
    Read(std::io::Error),
    /// An image of zero width or height.
    #[error("has no pixels ({width} x {height})")]
    NoPixels { width: u64, height: u64 },
    /// An image above the texel limit of its use (`what`, e.g. "a texture").
    #[error("is {width} x {height} pixels, above the limit of {limit} pixels for {what}")]
    TooLarge {
        width: u64,
        height: u64,
        limit: u64,
        what: String,
    },
    /// `values` texel values (4 bytes each) that cannot be allocated.
    #[error("needs {} bytes of texels, more than can be allocated", 4 * .values)]
    Alloc { values: usize },
    /// The format could not be guessed from the bytes.
    #[error(transparent)]
    Guess(std::io::Error),
    /// A format the `image` crate knows but textures do not read.
    #[error("is a {format:?} image (supported: PNG, JPEG, BMP, Radiance HDR, OpenEXR)")]
    UnsupportedFormat { format: image::ImageFormat },
    /// No known format.
    #[error("is not a PNG, JPEG, BMP, Radiance HDR or OpenEXR image")]
    UnknownFormat,
    /// The header (dimensions) could not be read.
    #[error("has an unreadable image header: {0}")]
    Header(#[source] image::ImageError),
    /// The pixels could not be decoded.
    #[error("could not be decoded: {0}")]
    Decode(#[source] image::ImageError),
    /// A JPEG that cannot be decoded (see [`crate::textures::jpeg`]).
    #[error(transparent)]
    Jpeg(#[from] crate::textures::jpeg::JpegError),
    /// A decoded pixel layout textures do not convert.
    #[error("has an unsupported pixel layout {color:?}")]
    PixelLayout { color: image::ColorType },
    /// A NaN or infinite texel value (`index` counts values, channels interleaved).
    #[error("has a non-finite value ({value}) at value {index}")]
    NonFinite { value: f32, index: usize },
    /// The OpenEXR header could not be read.
    #[error("has an unreadable OpenEXR header: {0}")]
    ExrHeader(#[source] exr::error::Error),
    /// An OpenEXR file without layers.
    #[error("is an OpenEXR file without layers")]
    ExrNoLayers,
    /// A deep OpenEXR image.
    #[error("is a deep OpenEXR image (not supported for textures)")]
    ExrDeep,
    /// The OpenEXR pixels could not be decoded.
    #[error("could not be decoded as OpenEXR: {0}")]
    ExrDecode(#[source] exr::error::Error),
    /// OpenEXR channels without R, G, B or Y (and not a single channel).
    #[error("has OpenEXR channels [{}]: a texture needs R, G, B or Y", .channels.join(", "))]
    ExrChannels { channels: Vec<String> },
    /// A subsampled OpenEXR channel.
    #[error(
        "has OpenEXR channel {channel} with {samples} samples for {width} x {height} pixels (subsampled channels are not supported)"
    )]
    ExrSubsampled {
        channel: String,
        samples: usize,
        width: usize,
        height: usize,
    },
}

/// Reads and decodes an image. `raw`: keep 8/16-bit values as stored (scaled to
/// [0, 1]) instead of decoding sRGB. The error is a short reason without the path.
pub fn load_image(path: &Path, raw: bool) -> Result<ImageData, ImageFileError> {
    load_image_within(path, raw, MAX_TEXELS, "a texture")
}

/// [`load_image`] with a smaller texel limit `max_texels` for a use (`what`) that
/// keeps more per texel, checked from the header before decoding.
pub fn load_image_within(
    path: &Path,
    raw: bool,
    max_texels: u64,
    what: &str,
) -> Result<ImageData, ImageFileError> {
    let bytes = read_regular(path, MAX_IMAGE_BYTES)
        .map_err(|e| ImageFileError::Read(std::io::Error::other(e)))?;
    let limit = Limit {
        texels: max_texels.min(MAX_TEXELS),
        what,
    };
    if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        decode_exr(&bytes, &limit)
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        decode_jpeg(&bytes, raw, &limit)
    } else {
        decode_ldr_or_hdr(&bytes, raw, &limit)
    }
}

/// The largest image a use accepts.
struct Limit<'a> {
    texels: u64,
    what: &'a str,
}

fn check_size(width: u64, height: u64, limit: &Limit) -> Result<(), ImageFileError> {
    if width == 0 || height == 0 {
        return Err(ImageFileError::NoPixels { width, height });
    }
    if width.saturating_mul(height) > limit.texels {
        return Err(ImageFileError::TooLarge {
            width,
            height,
            limit: limit.texels,
            what: limit.what.to_string(),
        });
    }
    Ok(())
}

/// A buffer of `n` texel values, or an error when it cannot be allocated.
fn texel_buffer(n: usize) -> Result<Vec<f32>, ImageFileError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n)
        .map_err(|_| ImageFileError::Alloc { values: n })?;
    Ok(v)
}

fn decode_ldr_or_hdr(bytes: &[u8], raw: bool, limit: &Limit) -> Result<ImageData, ImageFileError> {
    use image::{DynamicImage, ImageFormat, ImageReader};
    let reader = || -> Result<ImageReader<Cursor<&[u8]>>, ImageFileError> {
        let r = ImageReader::new(Cursor::new(bytes))
            .with_guessed_format()
            .map_err(ImageFileError::Guess)?;
        match r.format() {
            Some(ImageFormat::Png | ImageFormat::Jpeg | ImageFormat::Bmp | ImageFormat::Hdr) => {
                Ok(r)
            }
            Some(format) => Err(ImageFileError::UnsupportedFormat { format }),
            None => Err(ImageFileError::UnknownFormat),
        }
    };
    let (w, h) = reader()?
        .into_dimensions()
        .map_err(ImageFileError::Header)?;
    check_size(w as u64, h as u64, limit)?;
    let mut r = reader()?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    limits.max_alloc = Some(MAX_DECODE_ALLOC);
    r.limits(limits);
    let img = r.decode().map_err(ImageFileError::Decode)?;
    let (width, height) = (img.width() as usize, img.height() as usize);
    check_size(width as u64, height as u64, limit)?;
    let n = width * height;
    // Grey (with or without alpha) stays one channel; everything else becomes RGB,
    // alpha dropped, as Mitsuba's bitmap texture does.
    let grey = matches!(
        img,
        DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageLuma16(_)
            | DynamicImage::ImageLumaA16(_)
    );
    let channels = if grey { 1 } else { 3 };
    let mut data = texel_buffer(n * channels)?;
    let srgb = !raw;
    let decode8 = |v: u8| {
        let f = v as f32 / 255.0;
        if srgb {
            srgb_to_linear(f)
        } else {
            f
        }
    };
    let decode16 = |v: u16| {
        let f = v as f32 / 65535.0;
        if srgb {
            srgb_to_linear(f)
        } else {
            f
        }
    };
    match &img {
        DynamicImage::ImageLuma8(b) => data.extend(b.pixels().map(|p| decode8(p.0[0]))),
        DynamicImage::ImageLumaA8(b) => data.extend(b.pixels().map(|p| decode8(p.0[0]))),
        DynamicImage::ImageLuma16(b) => data.extend(b.pixels().map(|p| decode16(p.0[0]))),
        DynamicImage::ImageLumaA16(b) => data.extend(b.pixels().map(|p| decode16(p.0[0]))),
        DynamicImage::ImageRgb8(b) => data.extend(b.pixels().flat_map(|p| p.0.map(decode8))),
        DynamicImage::ImageRgba8(b) => data.extend(
            b.pixels()
                .flat_map(|p| [p.0[0], p.0[1], p.0[2]].map(decode8)),
        ),
        DynamicImage::ImageRgb16(b) => data.extend(b.pixels().flat_map(|p| p.0.map(decode16))),
        DynamicImage::ImageRgba16(b) => data.extend(
            b.pixels()
                .flat_map(|p| [p.0[0], p.0[1], p.0[2]].map(decode16)),
        ),
        // Radiance HDR (and any float image): linear already.
        DynamicImage::ImageRgb32F(b) => data.extend(b.pixels().flat_map(|p| p.0)),
        DynamicImage::ImageRgba32F(b) => {
            data.extend(b.pixels().flat_map(|p| [p.0[0], p.0[1], p.0[2]]))
        }
        other => {
            return Err(ImageFileError::PixelLayout {
                color: other.color(),
            })
        }
    }
    check_values(&data)?;
    Ok(ImageData {
        width,
        height,
        channels,
        data,
    })
}

/// JPEG through [`crate::textures::jpeg`], which decodes as libjpeg (Mitsuba's
/// decoder) does: the size is checked from the frame header before decoding.
fn decode_jpeg(bytes: &[u8], raw: bool, limit: &Limit) -> Result<ImageData, ImageFileError> {
    use crate::textures::jpeg;
    let (w, h) = jpeg::dimensions(bytes)?;
    check_size(w as u64, h as u64, limit)?;
    let img = jpeg::decode(bytes, limit.texels)?;
    let mut data = texel_buffer(img.data.len())?;
    if raw {
        data.extend(img.data.iter().map(|&v| v as f32 / 255.0));
    } else {
        let mut lut = [0f32; 256];
        for (i, l) in lut.iter_mut().enumerate() {
            *l = srgb_to_linear(i as f32 / 255.0);
        }
        data.extend(img.data.iter().map(|&v| lut[v as usize]));
    }
    Ok(ImageData {
        width: img.width,
        height: img.height,
        channels: img.channels,
        data,
    })
}

/// Texels must be finite: a NaN or infinity would reach every path that reads it.
fn check_values(data: &[f32]) -> Result<(), ImageFileError> {
    match data.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(ImageFileError::NonFinite {
            value: data[index],
            index,
        }),
        None => Ok(()),
    }
}

fn decode_exr(bytes: &[u8], limit: &Limit) -> Result<ImageData, ImageFileError> {
    use exr::prelude::*;
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(ImageFileError::ExrHeader)?;
    let header = meta.headers.first().ok_or(ImageFileError::ExrNoLayers)?;
    if header.deep {
        return Err(ImageFileError::ExrDeep);
    }
    let size = header.layer_size;
    check_size(size.width() as u64, size.height() as u64, limit)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(ImageFileError::ExrDecode)?;
    let layer = &image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    check_size(width as u64, height as u64, limit)?;
    let n = width * height;
    let channels = &layer.channel_data.list;
    let find = |name: &str| {
        channels.iter().find(|c| {
            let s = c.name.to_string();
            s == name || s.ends_with(&format!(".{name}"))
        })
    };
    let picked: Vec<&AnyChannel<FlatSamples>> = match (find("R"), find("G"), find("B"), find("Y")) {
        (Some(r), Some(g), Some(b), _) => vec![r, g, b],
        (_, _, _, Some(y)) => vec![y],
        _ if channels.len() == 1 => vec![&channels[0]],
        _ => {
            return Err(ImageFileError::ExrChannels {
                channels: channels.iter().map(|c| c.name.to_string()).collect(),
            });
        }
    };
    for c in &picked {
        if c.sample_data.len() != n {
            return Err(ImageFileError::ExrSubsampled {
                channel: c.name.to_string(),
                samples: c.sample_data.len(),
                width,
                height,
            });
        }
    }
    let mut data = texel_buffer(n * picked.len())?;
    for i in 0..n {
        for c in &picked {
            data.push(c.sample_data.value_by_flat_index(i).to_f32());
        }
    }
    check_values(&data)?;
    Ok(ImageData {
        width,
        height,
        channels: picked.len(),
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn write_png(dir: &Path, name: &str, img: image::DynamicImage) -> PathBuf {
        let p = dir.join(name);
        img.save(&p).unwrap();
        p
    }

    /// CRC-32 of a PNG chunk (type and data), to forge valid headers.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }

    #[test]
    fn srgb_bytes_decode_to_linear_unless_raw() {
        let dir = tempfile::tempdir().unwrap();
        let rgb = image::RgbImage::from_raw(2, 1, vec![128, 0, 255, 10, 64, 200]).unwrap();
        let p = write_png(dir.path(), "a.png", rgb.into());
        let img = load_image(&p, false).unwrap();
        assert_eq!((img.width, img.height, img.channels), (2, 1, 3));
        assert!((img.data[0] - 0.215_860_5).abs() < 1e-6, "{}", img.data[0]);
        assert_eq!(img.data[1], 0.0);
        assert!((img.data[2] - 1.0).abs() < 1e-6);
        // 10/255 lies on the linear segment: / 12.92.
        assert!((img.data[3] - 10.0 / 255.0 / 12.92).abs() < 1e-7);
        let raw = load_image(&p, true).unwrap();
        let bytes = [128u8, 0, 255, 10, 64, 200];
        for (v, b) in raw.data.iter().zip(bytes) {
            assert_eq!(*v, b as f32 / 255.0);
        }
    }

    #[test]
    fn bmp_decodes_as_the_same_png_does() {
        // Mitsuba reads BMP (e.g. its projector docs scene's flower.bmp) as 8-bit sRGB.
        let dir = tempfile::tempdir().unwrap();
        let bytes = vec![128, 0, 255, 10, 64, 200, 3, 90, 250, 255, 255, 1];
        let rgb = image::RgbImage::from_raw(2, 2, bytes).unwrap();
        let png = write_png(dir.path(), "a.png", rgb.clone().into());
        let bmp = write_png(dir.path(), "a.bmp", rgb.into());
        assert!(std::fs::read(&bmp).unwrap().starts_with(b"BM"));
        for raw in [false, true] {
            let (a, b) = (
                load_image(&png, raw).unwrap(),
                load_image(&bmp, raw).unwrap(),
            );
            assert_eq!(
                (a.width, a.height, a.channels, a.data),
                (b.width, b.height, b.channels, b.data)
            );
        }
    }

    #[test]
    fn alpha_is_dropped_and_grey_stays_one_channel() {
        let dir = tempfile::tempdir().unwrap();
        let rgba = image::RgbaImage::from_raw(1, 1, vec![255, 0, 51, 7]).unwrap();
        let img = load_image(&write_png(dir.path(), "rgba.png", rgba.into()), true).unwrap();
        assert_eq!(img.channels, 3);
        assert_eq!(img.data, vec![1.0, 0.0, 0.2]);
        let la = image::GrayAlphaImage::from_raw(2, 1, vec![51, 0, 255, 9]).unwrap();
        let img = load_image(&write_png(dir.path(), "la.png", la.into()), true).unwrap();
        assert_eq!((img.channels, img.data.clone()), (1, vec![0.2, 1.0]));
        let g16 =
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(1, 1, vec![65535u16]).unwrap();
        let img = load_image(&write_png(dir.path(), "g16.png", g16.into()), false).unwrap();
        assert!((img.data[0] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn exr_values_are_linear_and_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        exr::prelude::write_rgb_file(&p, 2, 2, |x, y| {
            (x as f32 + 2.0 * y as f32, 0.5f32, 10.0f32)
        })
        .unwrap();
        let img = load_image(&p, false).unwrap();
        assert_eq!((img.width, img.height, img.channels), (2, 2, 3));
        // Row-major from the first row: (0,0), (1,0), (0,1), (1,1).
        let r: Vec<f32> = img.data.chunks(3).map(|c| c[0]).collect();
        assert_eq!(r, vec![0.0, 1.0, 2.0, 3.0]);
        assert_eq!(img.data[1], 0.5);
        assert_eq!(img.data[2], 10.0);
    }

    #[test]
    fn hostile_images_are_one_line_errors() {
        let dir = tempfile::tempdir().unwrap();
        let rgb = image::RgbImage::from_raw(4, 4, vec![7; 48]).unwrap();
        let p = write_png(dir.path(), "ok.png", rgb.into());
        let good = std::fs::read(&p).unwrap();
        let check = |name: &str, bytes: &[u8], want: &str| {
            let f = dir.path().join(name);
            std::fs::write(&f, bytes).unwrap();
            let e = load_image(&f, false).unwrap_err().to_string();
            assert!(e.contains(want), "{name}: {e}");
            assert!(!e.contains('\n'), "{name}: {e}");
        };
        check("trunc.png", &good[..good.len() / 2], "decoded");
        check("empty.png", b"", "not a PNG");
        check("text.png", b"hello world, not an image", "not a PNG");
        check("gif.gif", b"GIF89a\x01\x00\x01\x00\x00\x00\x00", "Gif");
        check("exr.exr", &[0x76, 0x2f, 0x31, 0x01, 2, 0, 0], "OpenEXR");
        // A valid header that claims 100000 x 100000 pixels: refused before decoding.
        let mut huge = good.clone();
        huge[16..20].copy_from_slice(&100_000u32.to_be_bytes());
        huge[20..24].copy_from_slice(&100_000u32.to_be_bytes());
        let crc = crc32(&huge[12..29]);
        huge[29..33].copy_from_slice(&crc.to_be_bytes());
        check("huge.png", &huge, "above the limit");
        // Zero width is no image (the decoder refuses it, or we do).
        let mut zero = good.clone();
        zero[16..20].copy_from_slice(&0u32.to_be_bytes());
        let crc = crc32(&zero[12..29]);
        zero[29..33].copy_from_slice(&crc.to_be_bytes());
        let f = dir.path().join("zero.png");
        std::fs::write(&f, &zero).unwrap();
        let e = load_image(&f, false).unwrap_err().to_string();
        assert!(
            e.contains("unreadable image header") && e.contains("Invalid image dimensions")
                || e.contains("has no pixels (0 x 4)"),
            "{e}"
        );
        assert!(load_image(dir.path(), false)
            .unwrap_err()
            .to_string()
            .contains("directory"));
    }
}
