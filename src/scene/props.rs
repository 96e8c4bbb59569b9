//! The parameters of one XML plugin element (`<float name=...>`, `<rgb ...>`, ...),
//! read by name with types checked, and a final check that no parameter was left
//! unread: an unknown or misspelt parameter is an error, never a silent skip.

use super::ctx::{scene_number, scene_numbers, Ctx};
use super::error::SceneError;
use super::to_world::parse_transform;
use crate::scene::spectrum::{
    blackbody_to_srgb, list_to_srgb, uniform_to_srgb, SpectrumUse, UNBOUNDED_SPECTRA,
};
use crate::spectral::curve::Curve;
use glam::{DMat4, Vec3};
use roxmltree::Node;
use std::collections::HashMap;

/// A typed parameter value.
#[derive(Clone, Debug)]
pub enum Value {
    Float(f64),
    Integer(i64),
    Boolean(bool),
    Str(String),
    Rgb([f64; 3]),
    /// `<spectrum value="x"/>`: uniform (grey for reflectances, Mitsuba's purple-ish
    /// sRGB of the equal-energy spectrum for emission).
    Uniform(f64),
    /// `<spectrum value="w1:v1, w2:v2, ...">` or `<spectrum filename=...>`: wavelengths
    /// (nm, increasing) and values, converted when the plugin reads it
    /// (`scene::spectrum`).
    Spectrum(Vec<f64>, Vec<f64>),
    /// `<spectrum type="blackbody">`: Planck's law at `temperature` kelvin within
    /// `range` nm (`spectral::curve::blackbody`). Emission only, and only in the
    /// spectral mode (Mitsuba 3's RGB and mono variants refuse it).
    Blackbody {
        temperature: f32,
        range: [f32; 2],
    },
    Point([f64; 3]),
    Transform(DMat4),
}

struct Entry<'a, 'i> {
    node: Node<'a, 'i>,
    value: Value,
    used: bool,
}

/// The parameters of one plugin element, plus its nested object elements.
pub struct Props<'a, 'i, 'c> {
    pub ctx: &'c Ctx<'c>,
    pub node: Node<'a, 'i>,
    entries: HashMap<String, Entry<'a, 'i>>,
    /// Nested plugin elements (`bsdf`, `emitter`, `ref`, `film`, ...) in document order.
    pub objects: Vec<Node<'a, 'i>>,
}

/// Tags of nested plugin elements (everything else in a plugin is a parameter).
pub const OBJECT_TAGS: &[&str] = &[
    "bsdf",
    "emitter",
    "shape",
    "sensor",
    "film",
    "sampler",
    "rfilter",
    "integrator",
    "ref",
    "texture",
    "medium",
    "phase",
    "volume",
    "profile",
    "TemporalProfile",
];

impl<'a, 'i, 'c> Props<'a, 'i, 'c> {
    pub fn parse(ctx: &'c Ctx<'c>, node: Node<'a, 'i>) -> Result<Self, SceneError> {
        let mut entries = HashMap::new();
        let mut objects = Vec::new();
        for child in node.children().filter(|c| c.is_element()) {
            let tag = child.tag_name().name();
            if OBJECT_TAGS.contains(&tag) {
                objects.push(child);
                continue;
            }
            let name = ctx.required_attr(child, "name")?;
            let value = Self::parse_value(ctx, child, tag)?;
            if entries.contains_key(&name) {
                return Err(ctx.err(child, format!("parameter '{name}' given twice")));
            }
            entries.insert(
                name,
                Entry {
                    node: child,
                    value,
                    used: false,
                },
            );
        }
        Ok(Props {
            ctx,
            node,
            entries,
            objects,
        })
    }

    fn parse_value(ctx: &Ctx, node: Node, tag: &str) -> Result<Value, SceneError> {
        let bad = |what: &str, v: &str| ctx.err(node, format!("'{v}' is not {what}"));
        let numbers = |v: &str| scene_numbers(v).map_err(|e| ctx.err(node, e.to_string()));
        Ok(match tag {
            "float" => {
                let v = ctx.required_attr(node, "value")?;
                Value::Float(scene_number(&v).map_err(|e| ctx.err(node, e.to_string()))?)
            }
            "integer" => {
                let v = ctx.required_attr(node, "value")?;
                Value::Integer(v.trim().parse().map_err(|_| bad("an integer", &v))?)
            }
            "boolean" => {
                let v = ctx.required_attr(node, "value")?;
                // Mitsuba compares lower-cased: "True" and "FALSE" are booleans too.
                Value::Boolean(match v.trim().to_ascii_lowercase().as_str() {
                    "true" => true,
                    "false" => false,
                    _ => return Err(bad("true or false", &v)),
                })
            }
            "string" => Value::Str(ctx.required_attr(node, "value")?),
            "spectrum" => parse_spectrum(ctx, node)?,
            "rgb" | "color" => {
                let v = ctx.required_attr(node, "value")?;
                let f = numbers(&v)?;
                match f.len() {
                    1 => Value::Rgb([f[0]; 3]),
                    3 => Value::Rgb([f[0], f[1], f[2]]),
                    _ => return Err(bad("one or three numbers", &v)),
                }
            }
            "point" | "vector" => {
                let mut p = [0.0; 3];
                if let Some(v) = ctx.attr(node, "value")? {
                    let f = numbers(&v)?;
                    if f.len() != 3 {
                        return Err(bad("three numbers", &v));
                    }
                    p.copy_from_slice(&f);
                }
                for (i, axis) in ["x", "y", "z"].iter().enumerate() {
                    if let Some(v) = ctx.attr(node, axis)? {
                        p[i] = scene_number(&v)
                            .map_err(|e| ctx.err(node, format!("attribute '{axis}': {e}")))?;
                    }
                }
                Value::Point(p)
            }
            "transform" => Value::Transform(parse_transform(ctx, node)?),
            other => {
                return Err(ctx.err(
                    node,
                    format!("unknown element <{other}> (supported: float, integer, boolean, string, rgb, spectrum, point, vector, transform, and nested plugins)"),
                ))
            }
        })
    }

    fn take(&mut self, name: &str) -> Option<(Node<'a, 'i>, Value)> {
        self.entries.get_mut(name).map(|e| {
            e.used = true;
            (e.node, e.value.clone())
        })
    }

    fn type_err(&self, node: Node, name: &str, want: &str) -> SceneError {
        self.ctx
            .err(node, format!("parameter '{name}' must be {want}"))
    }

    /// The value of a parameter without marking it read.
    pub fn peek(&self, name: &str) -> Option<&Value> {
        self.entries.get(name).map(|e| &e.value)
    }

    pub fn float(&mut self, name: &str) -> Result<Option<f64>, SceneError> {
        match self.take(name) {
            None => Ok(None),
            Some((_, Value::Float(v))) => Ok(Some(v)),
            Some((_, Value::Integer(v))) => Ok(Some(v as f64)),
            Some((n, _)) => Err(self.type_err(n, name, "a <float>")),
        }
    }

    pub fn float_or(&mut self, name: &str, default: f64) -> Result<f64, SceneError> {
        Ok(self.float(name)?.unwrap_or(default))
    }

    pub fn integer(&mut self, name: &str) -> Result<Option<i64>, SceneError> {
        match self.take(name) {
            None => Ok(None),
            Some((_, Value::Integer(v))) => Ok(Some(v)),
            Some((n, _)) => Err(self.type_err(n, name, "an <integer>")),
        }
    }

    pub fn boolean_or(&mut self, name: &str, default: bool) -> Result<bool, SceneError> {
        match self.take(name) {
            None => Ok(default),
            Some((_, Value::Boolean(v))) => Ok(v),
            Some((n, _)) => Err(self.type_err(n, name, "a <boolean>")),
        }
    }

    pub fn string(&mut self, name: &str) -> Result<Option<String>, SceneError> {
        match self.take(name) {
            None => Ok(None),
            Some((_, Value::Str(v))) => Ok(Some(v)),
            Some((n, _)) => Err(self.type_err(n, name, "a <string>")),
        }
    }

    /// An rgb colour; a `<float>` gives a grey.
    /// A colour parameter (reflectances and the like): `<rgb>`, `<float>` or `<spectrum>`.
    pub fn rgb(&mut self, name: &str) -> Result<Option<Vec3>, SceneError> {
        self.colour(name, SpectrumUse::Reflectance)
    }

    /// An emitted colour (radiance, intensity): as [`Self::rgb`], with Mitsuba's rules
    /// for spectra of emitters (no D65 weighting, no upper clamp, uniform spectra
    /// purple-ish).
    pub fn emission(&mut self, name: &str) -> Result<Option<Vec3>, SceneError> {
        self.colour(name, SpectrumUse::Emission)
    }

    fn colour(&mut self, name: &str, usage: SpectrumUse) -> Result<Option<Vec3>, SceneError> {
        let usage = if usage == SpectrumUse::Reflectance && UNBOUNDED_SPECTRA.contains(&name) {
            SpectrumUse::Unbounded
        } else {
            usage
        };
        if usage == SpectrumUse::Emission {
            let curve = match self.peek(name) {
                Some(Value::Uniform(v)) => Some(Curve::Uniform(*v as f32)),
                Some(Value::Spectrum(w, v)) => Some(Curve::Irregular {
                    wavelengths: w.iter().map(|&x| x as f32).collect(),
                    values: v.iter().map(|&x| x as f32).collect(),
                }),
                Some(Value::Blackbody { temperature, range }) => Some(Curve::Blackbody {
                    temperature: *temperature,
                    range: *range,
                }),
                _ => None,
            };
            self.ctx.set_emission_spectrum(curve);
        }
        match self.take(name) {
            None => Ok(None),
            Some((_, Value::Rgb(c))) => Ok(Some(Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))),
            Some((_, Value::Float(v))) => Ok(Some(Vec3::splat(v as f32))),
            Some((n, Value::Uniform(v))) => {
                let c = uniform_to_srgb(v, usage);
                if c.iter().any(|x| !x.is_finite()) {
                    return Err(self.ctx.err(
                        n,
                        format!("spectrum '{name}' converts to a colour beyond single precision ({c:?}): its value is too large"),
                    ));
                }
                Ok(Some(Vec3::from_array(c)))
            }
            Some((n, Value::Spectrum(w, v))) => {
                let (c, clamped) = list_to_srgb(&w, &v, usage);
                if c.iter().any(|x| !x.is_finite()) {
                    return Err(self.ctx.err(
                        n,
                        format!("spectrum '{name}' converts to a colour beyond single precision ({c:?}): its values are too large"),
                    ));
                }
                if clamped {
                    self.ctx.warn(
                        n,
                        format!("spectrum '{name}' is out of the sRGB gamut; clamped to {c:?}, as Mitsuba does"),
                    );
                }
                Ok(Some(Vec3::from_array(c)))
            }
            Some((n, Value::Blackbody { temperature, range })) => {
                if usage != SpectrumUse::Emission {
                    return Err(self.ctx.err(
                        n,
                        format!("'{name}' cannot be a blackbody spectrum: tstat reads one only as an emitter's radiance, intensity or irradiance"),
                    ));
                }
                if !self.ctx.mode.is_spectral() {
                    return Err(self.ctx.err(
                        n,
                        format!("'{name}' is a blackbody spectrum, which renders only with --mode spectral or spectral_polarized (Mitsuba 3's RGB and mono variants refuse it too: \"Not implemented for non-spectral modes\")"),
                    ));
                }
                // Finite: checked when the spectrum was read (`parse_blackbody`).
                let c = blackbody_to_srgb(temperature, range).unwrap_or([0.0; 3]);
                Ok(Some(Vec3::from_array(c)))
            }
            Some((n, _)) => Err(self.type_err(n, name, "an <rgb>, <spectrum> or <float>")),
        }
    }

    /// In the spectral mode, a BSDF's colour parameter given as a `<spectrum>` (a
    /// value, a `wavelength:value` list or a `.spd` file), which that mode uses as
    /// given, as Mitsuba's spectral variants do (its `uniform` and `irregular`
    /// spectra): the spectrum and its RGB as [`Self::rgb`] reads it (what the
    /// G-buffer records), without the gamut warning (nothing is clamped at a path's
    /// wavelengths). Values must be non-negative (Mitsuba's spectral variants refuse
    /// negative ones); a reflectance above 1 is a warning. `None` in the other modes,
    /// for any other value, and when a nested texture of the same name makes the
    /// parameter given twice (the texture reader's error).
    pub fn given_spectrum(&mut self, name: &str) -> Result<Option<(Curve, Vec3)>, SceneError> {
        if !self.ctx.mode.is_spectral()
            || self
                .objects
                .iter()
                .any(|o| self.ctx.attr(*o, "name").ok().flatten().as_deref() == Some(name))
        {
            return Ok(None);
        }
        let usage = if UNBOUNDED_SPECTRA.contains(&name) {
            SpectrumUse::Unbounded
        } else {
            SpectrumUse::Reflectance
        };
        let (curve, rgb, values) = match self.peek(name) {
            Some(Value::Uniform(v)) => (
                Curve::Uniform(*v as f32),
                uniform_to_srgb(*v, usage),
                vec![*v],
            ),
            Some(Value::Spectrum(w, v)) => (
                Curve::Irregular {
                    wavelengths: w.iter().map(|&x| x as f32).collect(),
                    values: v.iter().map(|&x| x as f32).collect(),
                },
                list_to_srgb(w, v, usage).0,
                v.clone(),
            ),
            _ => return Ok(None),
        };
        let Some((n, _)) = self.take(name) else {
            return Ok(None);
        };
        if rgb.iter().any(|x| !x.is_finite()) {
            return Err(self.ctx.err(
                n,
                format!("spectrum '{name}' converts to a colour beyond single precision ({rgb:?}): its values are too large"),
            ));
        }
        if let Some(v) = values.iter().find(|&&v| v < 0.0) {
            return Err(self.ctx.err(
                n,
                format!("spectrum '{name}' has the negative value {v}: the spectral mode uses it as given, and Mitsuba's spectral variants refuse negative values too"),
            ));
        }
        let top = values.iter().fold(0.0f64, |m, &v| m.max(v));
        if usage == SpectrumUse::Reflectance && top > 1.0 {
            self.ctx.warn(
                n,
                format!("spectrum '{name}' reaches {top}, above 1: the material reflects more energy than it receives at those wavelengths"),
            );
        }
        // The RGB stands in for the spectrum (the G-buffer, the checks of constants):
        // an optical constant's, unclamped, may be negative out of gamut.
        Ok(Some((curve, Vec3::from_array(rgb).max(Vec3::ZERO))))
    }

    pub fn point(&mut self, name: &str) -> Result<Option<[f64; 3]>, SceneError> {
        match self.take(name) {
            None => Ok(None),
            Some((_, Value::Point(p))) => Ok(Some(p)),
            Some((n, _)) => Err(self.type_err(n, name, "a <point>")),
        }
    }

    pub fn transform(&mut self, name: &str) -> Result<Option<DMat4>, SceneError> {
        match self.take(name) {
            None => Ok(None),
            Some((_, Value::Transform(m))) => Ok(Some(m)),
            Some((n, _)) => Err(self.type_err(n, name, "a <transform>")),
        }
    }

    /// Marks a parameter as accepted without using it (documented as ignored).
    pub fn ignore(&mut self, name: &str) {
        self.take(name);
    }

    /// An error located at a named parameter, or at the element when it is absent.
    pub fn err_at(&self, name: &str, message: impl Into<String>) -> SceneError {
        let node = self.entries.get(name).map_or(self.node, |e| e.node);
        self.ctx.err(node, message)
    }

    pub fn err(&self, message: impl Into<String>) -> SceneError {
        self.ctx.err(self.node, message)
    }

    /// A warning located at a named parameter, or at the element when it is absent.
    pub fn warn_at(&self, name: &str, message: impl Into<String>) {
        let node = self.entries.get(name).map_or(self.node, |e| e.node);
        self.ctx.warn(node, message)
    }

    /// Fails on the first parameter nobody read.
    pub fn finish(self) -> Result<(), SceneError> {
        let mut unused: Vec<_> = self.entries.iter().filter(|(_, e)| !e.used).collect();
        unused.sort_by_key(|(_, e)| e.node.range().start);
        if let Some((name, e)) = unused.first() {
            return Err(self.ctx.err(
                e.node,
                format!(
                    "unknown parameter '{name}' for <{}>",
                    Ctx::describe(self.node)
                ),
            ));
        }
        Ok(())
    }
}

/// The spectrum plugins read as `<spectrum type="...">` (the plugin table's `spectrum`
/// family): Mitsuba 3's `blackbody`.
pub const SPECTRA: &[&str] = &["blackbody"];

/// `<spectrum type="blackbody">` with Mitsuba 3's parameters: `temperature` (kelvin,
/// required), `wavelength_min` and `wavelength_max` (nm, default 360 and 830). The
/// temperature must be positive, the range non-empty, and Planck's law finite in single
/// precision over the wavelengths a path samples (above about 3e11 K it is not).
fn parse_blackbody(ctx: &Ctx, node: Node) -> Result<Value, SceneError> {
    for a in ["value", "filename"] {
        if ctx.attr(node, a)?.is_some() {
            return Err(ctx.err(
                node,
                format!("a blackbody spectrum takes nested parameters (temperature, wavelength_min, wavelength_max), not the attribute '{a}'"),
            ));
        }
    }
    let mut p = Props::parse(ctx, node)?;
    let t = p
        .float("temperature")?
        .ok_or_else(|| p.err("a blackbody spectrum needs 'temperature' (kelvin)"))?;
    let (lo, hi) = (
        p.float_or("wavelength_min", 360.0)?,
        p.float_or("wavelength_max", 830.0)?,
    );
    if let Some(&o) = p.objects.first() {
        return Err(ctx.err(o, "unexpected nested element in a blackbody <spectrum>"));
    }
    let temperature = t as f32;
    if temperature.is_nan() || temperature <= 0.0 {
        return Err(p.err_at(
            "temperature",
            format!("the temperature of a blackbody must be positive (kelvin), got {t}"),
        ));
    }
    let range = [lo as f32, hi as f32];
    if !(range[0] >= 0.0 && range[0] < range[1]) {
        return Err(p.err(format!(
            "wavelength_min and wavelength_max must satisfy 0 <= min < max (nm), got {lo} and {hi}"
        )));
    }
    if let Err(l) = blackbody_to_srgb(temperature, range) {
        return Err(p.err_at(
            "temperature",
            format!("Planck's law at {t} K overflows single precision at {l} nm"),
        ));
    }
    p.finish()?;
    Ok(Value::Blackbody { temperature, range })
}

/// The largest `.spd` file read (Mitsuba has no limit; measured spectra of a few
/// million samples run to tens of MB): 64 MiB, about 4 million lines.
pub const MAX_SPECTRUM_FILE_BYTES: u64 = 64 << 20;

/// A `<spectrum>` element: `value="x"` (uniform), `value="r, g, b"` (taken as RGB),
/// `value="w1:v1, w2:v2, ..."` or `filename="..."` (Mitsuba's `.spd`: one `wavelength
/// value` pair per line, `#` comments).
fn parse_spectrum(ctx: &Ctx, node: Node) -> Result<Value, SceneError> {
    let bad = |msg: String| ctx.err(node, msg);
    if let Some(kind) = ctx.attr(node, "type")? {
        if !SPECTRA.contains(&kind.as_str()) {
            return Err(bad(format!(
                "spectrum type '{kind}' is not supported (supported: {}; a list is given as value=\"wavelength:value, ...\" or filename=\"FILE.spd\")",
                SPECTRA.join(", ")
            )));
        }
        return parse_blackbody(ctx, node);
    }
    let pairs: Vec<(f64, f64)> = match (ctx.attr(node, "value")?, ctx.attr(node, "filename")?) {
        (Some(_), Some(_)) => return Err(bad("give either 'value' or 'filename'".into())),
        (None, None) => return Err(bad("missing attribute 'value' (or 'filename')".into())),
        (Some(v), None) if !v.contains(':') => {
            let f = scene_numbers(&v).map_err(|e| bad(format!("value '{v}': {e}")))?;
            return match f.len() {
                1 => Ok(Value::Uniform(f[0])),
                3 => Ok(Value::Rgb([f[0], f[1], f[2]])),
                _ => Err(bad(format!(
                    "value '{v}': expected one number, three, or wavelength:value pairs"
                ))),
            };
        }
        (Some(v), None) => v
            .split(',')
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(|t| {
                let (w, x) = t
                    .split_once(':')
                    .ok_or_else(|| bad(format!("'{t}' is not a wavelength:value pair")))?;
                let w = scene_number(w).map_err(|e| bad(format!("wavelength in '{t}': {e}")))?;
                let x = scene_number(x).map_err(|e| bad(format!("value in '{t}': {e}")))?;
                Ok((w, x))
            })
            .collect::<Result<_, SceneError>>()?,
        (None, Some(f)) => {
            let path = ctx.resolve(&f);
            ctx.read_mesh_file(&path);
            let bytes = crate::io::read_regular(&path, MAX_SPECTRUM_FILE_BYTES)
                .map_err(|e| bad(format!("cannot read spectrum file '{f}': {e}")))?;
            let text = String::from_utf8_lossy(&bytes);
            let mut pairs = Vec::new();
            for (i, line) in text.lines().enumerate() {
                let line = line.split('#').next().unwrap_or("").trim();
                if line.is_empty() {
                    continue;
                }
                let f2 = scene_numbers(line).map_err(|e| bad(format!("{f}:{}: {e}", i + 1)))?;
                if f2.len() != 2 {
                    return Err(bad(format!("{f}:{}: expected 'wavelength value'", i + 1)));
                }
                pairs.push((f2[0], f2[1]));
            }
            pairs
        }
    };
    if pairs.len() < 2 {
        return Err(bad(
            "a spectrum needs at least two wavelength:value pairs".into()
        ));
    }
    if pairs.windows(2).any(|p| p[1].0 <= p[0].0) {
        return Err(bad("the wavelengths of a spectrum must increase".into()));
    }
    let (w, v) = pairs.into_iter().unzip();
    Ok(Value::Spectrum(w, v))
}
