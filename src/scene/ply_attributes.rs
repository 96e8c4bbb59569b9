//! Which extra PLY properties become mesh attributes, and their values, exactly as
//! Mitsuba 3.9.1's PLY loader (`src/shapes/ply.h`, `find_other_fields`, and the
//! struct conversion it asks for).
//!
//! Grouping, per element (`vertex_` or `face_` prefix), over the element's properties
//! in file order (those the mesh itself uses are reserved: `x y z nx ny nz u v` for
//! vertices, after Mitsuba renames the texture coordinate pair it uses to `u v`; the
//! vertex list for faces; `r g b a` for both):
//! - `r g b` (or `red green blue`, renamed to them when `r g b` are not all there),
//!   plus `a`/`alpha` when present: one attribute `PREFIX_color` of 3 (4) channels;
//! - consecutive properties `NAME_s0 NAME_s1 ...` sharing a prefix `NAME` with one-letter
//!   suffixes of one family, `x y z w`, `r g b a`, `0 1 2 3` or `1 2 3 4`, in order:
//!   one attribute `PREFIX_NAME` (`PREFIX_NAME_color` for the `r g b a` family) of
//!   1 or 3 channels (any other count is ignored, as is a prefix seen before, a name
//!   without `_`, or a suffix longer than one letter).
//!
//! Values (measured on Mitsuba 3.9.1, whose struct conversion gives integer
//! properties the `Normalized | Gamma` flags): `float`/`double` as they are; `uchar`
//! as the integer itself (0..255, not normalised: Mitsuba warns that colours should
//! be in [0, 1]); every other integer type `v / max` of its type (signed: over the
//! largest positive value) and then sRGB-decoded with `x <= 0.04045 ? x / 12.92 :
//! ((x + 0.055) / 1.055)^2.4` (so negatives are only divided by 12.92).

use ply_rs::ply::{Property, ScalarType};

/// One attribute to build: its name and the indices of its properties (channels) in
/// the element's property list.
#[derive(Clone, Debug, PartialEq)]
pub struct Descriptor {
    pub name: String,
    pub fields: Vec<usize>,
}

const POSTFIXES: [&[u8; 4]; 4] = [b"xr01", b"yg12", b"zb23", b"wa34"];

/// The attributes of an element whose scalar properties are `names` (file order,
/// after the renames above; list properties left out), `prefix` `"vertex_"` or
/// `"face_"`, `reserved` the names the mesh uses itself.
pub fn group(prefix: &str, names: &[String], reserved: &[&str]) -> Vec<Descriptor> {
    let mut names: Vec<String> = names.to_vec();
    let has = |names: &[String], n: &str| names.iter().any(|x| x == n);
    let pos = |names: &[String], n: &str| names.iter().position(|x| x == n);
    let mut out = Vec::new();
    if !(has(&names, "r") && has(&names, "g") && has(&names, "b"))
        && has(&names, "red")
        && has(&names, "green")
        && has(&names, "blue")
    {
        for (from, to) in [("red", "r"), ("green", "g"), ("blue", "b"), ("alpha", "a")] {
            if let Some(i) = pos(&names, from) {
                names[i] = to.into();
            }
        }
    }
    if let (Some(r), Some(g), Some(b)) = (pos(&names, "r"), pos(&names, "g"), pos(&names, "b")) {
        let mut fields = vec![r, g, b];
        if let Some(a) = pos(&names, "a") {
            fields.push(a);
        }
        out.push(Descriptor {
            name: format!("{prefix}color"),
            fields,
        });
    }
    let reserved = |n: &str| reserved.contains(&n) || matches!(n, "r" | "g" | "b" | "a");

    // A transliteration of Mitsuba's loop, quirks included.
    let mut seen: Vec<String> = Vec::new();
    let mut cur_prefix = String::new();
    let mut cur_postfix = 0usize;
    let mut level = 0usize;
    let mut reading = false;
    // Mitsuba takes the channels by name (`PREFIX_` + the family's first `level`
    // suffixes) when it flushes.
    let flush = |out: &mut Vec<Descriptor>,
                 seen: &mut Vec<String>,
                 cur_prefix: &str,
                 cur_postfix: usize,
                 level: usize| {
        if level != 1 && level != 3 {
            return;
        }
        let fields: Option<Vec<usize>> = (0..level)
            .map(|k| {
                let want = format!("{cur_prefix}_{}", POSTFIXES[k][cur_postfix] as char);
                names.iter().position(|x| *x == want)
            })
            .collect();
        let Some(fields) = fields else { return };
        let color = if cur_postfix == 1 { "_color" } else { "" };
        out.push(Descriptor {
            name: format!("{prefix}{cur_prefix}{color}"),
            fields,
        });
        seen.push(cur_prefix.to_string());
    };
    let n = names.len();
    let mut i = 0;
    while i < n {
        let name = names[i].clone();
        if reserved(&name) {
            i += 1;
            continue;
        }
        // No `_`, or a suffix longer than one character: not part of a family.
        let Some(us) = name.rfind('_').filter(|&us| name.len() - us - 1 == 1) else {
            if reading {
                flush(&mut out, &mut seen, &cur_prefix, cur_postfix, level);
                (cur_prefix, cur_postfix, level, reading) = (String::new(), 0, 0, false);
            }
            i += 1;
            continue;
        };
        let postfix = &name[us + 1..];
        let pre = name[..us].to_string();
        if reading && pre != cur_prefix {
            flush(&mut out, &mut seen, &cur_prefix, cur_postfix, level);
            (cur_prefix, cur_postfix, level, reading) = (String::new(), 0, 0, false);
        }
        if !reading && seen.contains(&pre) {
            while i < n && names[i].starts_with(&pre) {
                i += 1;
            }
            if i == n {
                break;
            }
            i += 1;
            continue;
        }
        let ch = postfix.as_bytes()[0];
        if !reading {
            let Some(j) = POSTFIXES[0].iter().position(|&c| c == ch) else {
                i += 1;
                continue;
            };
            reading = true;
            cur_postfix = j;
            cur_prefix = pre;
        } else if level >= 4 || ch != POSTFIXES[level][cur_postfix] {
            (cur_prefix, cur_postfix, level, reading) = (String::new(), 0, 0, false);
            while i < n && names[i].starts_with(&pre) {
                i += 1;
            }
            if i == n {
                break;
            }
        }
        level += 1;
        i += 1;
    }
    if reading {
        flush(&mut out, &mut seen, &cur_prefix, cur_postfix, level);
    }
    out
}

/// The type of a scalar property, for [`value`].
pub fn scalar_type(p: &Property) -> Option<ScalarType> {
    Some(match p {
        Property::Char(_) => ScalarType::Char,
        Property::UChar(_) => ScalarType::UChar,
        Property::Short(_) => ScalarType::Short,
        Property::UShort(_) => ScalarType::UShort,
        Property::Int(_) => ScalarType::Int,
        Property::UInt(_) => ScalarType::UInt,
        Property::Float(_) => ScalarType::Float,
        Property::Double(_) => ScalarType::Double,
        _ => return None,
    })
}

/// Mitsuba's value of a scalar property in an attribute (see the module notes).
pub fn value(p: &Property) -> f32 {
    let normalised = match *p {
        Property::Float(v) => return v,
        Property::Double(v) => return v as f32,
        Property::UChar(v) => return v as f32,
        Property::Char(v) => v as f64 / i8::MAX as f64,
        Property::Short(v) => v as f64 / i16::MAX as f64,
        Property::UShort(v) => v as f64 / u16::MAX as f64,
        Property::Int(v) => v as f64 / i32::MAX as f64,
        Property::UInt(v) => v as f64 / u32::MAX as f64,
        _ => return 0.0,
    } as f32;
    srgb_decode(normalised)
}

/// sRGB to linear as Mitsuba's `srgb_to_linear` (no special case for negatives).
fn srgb_decode(x: f32) -> f32 {
    if x <= 0.04045 {
        x * (1.0 / 12.92)
    } else {
        ((x + 0.055) * (1.0 / 1.055)).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    fn grouped(prefix: &str, v: &[&str], reserved: &[&str]) -> Vec<(String, Vec<usize>)> {
        group(prefix, &names(v), reserved)
            .into_iter()
            .map(|d| (d.name, d.fields))
            .collect()
    }

    #[test]
    fn colours_and_prefixed_groups_as_mitsuba() {
        let r = ["x", "y", "z", "nx", "ny", "nz", "u", "v"];
        // The attribute ply files of mitsuba-data.
        assert_eq!(
            grouped(
                "vertex_",
                &["x", "y", "z", "nx", "ny", "nz", "u", "v", "color_0", "color_1", "color_2"],
                &r
            ),
            vec![("vertex_color".into(), vec![8, 9, 10])]
        );
        assert_eq!(
            grouped("face_", &["color_0", "color_1", "color_2", "weight_0"], &[]),
            vec![
                ("face_color".into(), vec![0, 1, 2]),
                ("face_weight".into(), vec![3])
            ]
        );
        // red/green/blue/alpha -> vertex_color (4 channels); rgb suffixes -> NAME_color.
        assert_eq!(
            grouped(
                "vertex_",
                &["x", "y", "z", "red", "green", "blue", "alpha", "c_r", "c_g", "c_b"],
                &r
            ),
            vec![
                ("vertex_color".into(), vec![3, 4, 5, 6]),
                ("vertex_c_color".into(), vec![7, 8, 9])
            ]
        );
        // Two channels are ignored; a name without '_' is skipped; 1..3 family.
        assert_eq!(
            grouped(
                "vertex_",
                &["x", "y", "z", "k_x", "k_y", "conf", "m_1", "m_2", "m_3"],
                &r
            ),
            vec![("vertex_m".into(), vec![6, 7, 8])]
        );
        // A broken sequence drops the attribute and, as Mitsuba's loop does, the
        // field after it, and leaves its count at 1 so that the next one-field
        // attribute counts 2 and is dropped too.
        assert!(grouped("vertex_", &["x", "y", "z", "p_x", "p_z", "q_0", "w_0"], &r).is_empty());
        assert_eq!(
            grouped("vertex_", &["x", "y", "z", "p_x", "p_y", "p_z", "q_0"], &r),
            vec![
                ("vertex_p".into(), vec![3, 4, 5]),
                ("vertex_q".into(), vec![6])
            ]
        );
    }

    #[test]
    fn values_as_mitsuba_3_9_1_converts_them() {
        // Measured with mitsuba 3.9.1 (llvm_ad_rgb) on an ASCII PLY.
        assert_eq!(value(&Property::UChar(128)), 128.0);
        assert!((value(&Property::UShort(1)) - 1.18104e-6).abs() < 1e-11);
        assert_eq!(value(&Property::UShort(65535)), 1.0);
        assert!((value(&Property::UShort(7)) - 8.26727e-6).abs() < 1e-11);
        assert!((value(&Property::Char(-127)) + 0.0773994).abs() < 1e-7);
        assert!((value(&Property::Char(-128)) + 0.0780088).abs() < 1e-7);
        assert!((value(&Property::Char(-5)) + 0.00304722).abs() < 1e-8);
        assert_eq!(value(&Property::Int(i32::MAX)), 1.0);
        assert!((value(&Property::UInt(1)) - 1.80209e-11).abs() < 1e-15);
        assert_eq!(value(&Property::Double(2.5)), 2.5);
    }
}
