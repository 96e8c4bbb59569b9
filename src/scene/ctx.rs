//! The document a plugin is read from: its file and text, the `<default>` values that
//! `$name` references take, the folders searched for the files it names, the warnings
//! of the load, and the scene's number syntax (finite, single precision).

use super::error::SceneError;
use roxmltree::Node;
use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::path::Path;

/// How an element's text attributes are resolved: `$name` substitution from defaults.
/// Also collects the warnings of the load (legal but suspicious input).
pub struct Ctx<'a> {
    pub file: &'a Path,
    pub text: &'a str,
    pub defaults: &'a HashMap<String, String>,
    /// One line each, `file:line: <element>: message` (the caller adds "warning: ").
    warnings: RefCell<Vec<String>>,
    /// Bytes added by `$name` substitutions so far (bounded by [`MAX_EXPANDED_BYTES`]).
    expanded: Cell<usize>,
    /// Warnings recorded, including those beyond [`MAX_WARNINGS`].
    warning_count: Cell<usize>,
    /// Mesh files read, in document order.
    mesh_files: RefCell<Vec<std::path::PathBuf>>,
    /// Folders searched for the files the scene names, first match wins: the
    /// `<path>`s (latest first), then the scene file's folder (Mitsuba's file resolver).
    search: RefCell<Vec<std::path::PathBuf>>,
    /// A plugin type as the loaders spell it ([`Self::with_plugin_names`]).
    canonical: fn(String) -> String,
    /// The spectrum of the last emitted colour read, when the scene gave one
    /// (`<spectrum>`); the emitter being read takes it (`take_emission_spectrum`) for
    /// the spectral mode.
    emission_spectrum: RefCell<Option<crate::spectral::curve::Curve>>,
    /// The render mode the scene is read for (`--mode`): the spectral mode reads a
    /// few values as Mitsuba's spectral variants do (`scene::bsdfs::conductor_ior`).
    pub mode: super::mode::RenderMode,
}

/// Warnings kept with their location; the rest are counted.
pub const MAX_WARNINGS: usize = 10;

/// The largest magnitude a scene number may have: every number ends up in single
/// precision somewhere (positions, colours, IORs), where anything larger is infinite.
pub const MAX_NUMBER: f64 = f32::MAX as f64;

/// Why a token is not a scene number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NumberErrorKind {
    /// Not a number, or NaN or infinite.
    NotFinite,
    /// Finite, but beyond [`MAX_NUMBER`].
    Overflow,
}

/// A token of a scene file that is not a scene number (the token without its
/// surrounding whitespace).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NumberError {
    pub token: String,
    pub kind: NumberErrorKind,
}

impl std::fmt::Display for NumberError {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let t = &self.token;
        match self.kind {
            NumberErrorKind::NotFinite => write!(f, "'{t}' is not a finite number"),
            NumberErrorKind::Overflow => write!(
                f,
                "'{t}' overflows single precision (largest magnitude {MAX_NUMBER:.3e})"
            ),
        }
    }
}

impl std::error::Error for NumberError {}

/// Parses one number of a scene file: finite and within single precision.
pub fn scene_number(token: &str) -> Result<f64, NumberError> {
    let t = token.trim();
    let err = |kind| NumberError {
        token: t.to_string(),
        kind,
    };
    let v: f64 = t.parse().map_err(|_| err(NumberErrorKind::NotFinite))?;
    if !v.is_finite() {
        return Err(err(NumberErrorKind::NotFinite));
    }
    if v.abs() > MAX_NUMBER {
        return Err(err(NumberErrorKind::Overflow));
    }
    Ok(v)
}

/// Parses a list of numbers separated by commas and/or whitespace.
pub fn scene_numbers(s: &str) -> Result<Vec<f64>, NumberError> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(scene_number)
        .collect()
}

impl<'a> Ctx<'a> {
    pub fn new(file: &'a Path, text: &'a str, defaults: &'a HashMap<String, String>) -> Self {
        Ctx {
            file,
            text,
            defaults,
            warnings: RefCell::new(Vec::new()),
            expanded: Cell::new(0),
            warning_count: Cell::new(0),
            mesh_files: RefCell::new(Vec::new()),
            search: RefCell::new(vec![file.parent().unwrap_or(Path::new(".")).to_path_buf()]),
            canonical: std::convert::identity,
            emission_spectrum: RefCell::new(None),
            mode: super::mode::RenderMode::Rgb,
        }
    }

    /// Reads the scene for `mode`.
    pub fn with_mode(mut self, mode: super::mode::RenderMode) -> Self {
        self.mode = mode;
        self
    }

    /// Records the spectrum of the emitted colour just read (`None`: an RGB or grey).
    pub fn set_emission_spectrum(&self, s: Option<crate::spectral::curve::Curve>) {
        *self.emission_spectrum.borrow_mut() = s;
    }

    /// The spectrum of the emitted colour read last, if the scene gave one; cleared.
    pub fn take_emission_spectrum(&self) -> Option<crate::spectral::curve::Curve> {
        self.emission_spectrum.borrow_mut().take()
    }

    /// Reads plugin types through `canonical` (the plugin table's spelling of a name
    /// written in another case, `plugins::canonical_plugin_name`); without it, types
    /// stay as written.
    pub fn with_plugin_names(mut self, canonical: fn(String) -> String) -> Self {
        self.canonical = canonical;
        self
    }

    /// The folder of the file being read.
    pub fn dir(&self) -> &Path {
        self.file.parent().unwrap_or(Path::new("."))
    }

    /// A file the scene names, found as Mitsuba's file resolver does: absolute as it
    /// is; else the first folder of the search list that has it (the `<path>`s, latest
    /// first, then the scene's folder), then the folder of the file being read. A
    /// name found nowhere stays relative to the file being read (the error names it).
    pub fn resolve(&self, name: &str) -> std::path::PathBuf {
        let p = Path::new(name);
        if p.is_absolute() {
            return p.to_path_buf();
        }
        self.search
            .borrow()
            .iter()
            .map(|d| d.join(p))
            .chain(std::iter::once(self.dir().join(p)))
            .find(|c| c.exists())
            .unwrap_or_else(|| self.dir().join(p))
    }

    /// An included file: next to the including file first, then as [`Self::resolve`].
    pub fn resolve_near(&self, name: &str) -> std::path::PathBuf {
        let near = self.dir().join(name);
        if Path::new(name).is_relative() && near.exists() {
            near
        } else {
            self.resolve(name)
        }
    }

    /// Adds the command line's `-a` folders at the end of the search list, after the
    /// scene's folder (Mitsuba's `-a` appends to its file resolver).
    pub fn with_search_paths(self, dirs: &[std::path::PathBuf]) -> Self {
        self.search.borrow_mut().extend(dirs.iter().cloned());
        self
    }

    /// Puts `dir` first in the search list.
    pub fn prepend_search_path(&self, dir: std::path::PathBuf) {
        self.search.borrow_mut().insert(0, dir);
    }

    /// The context of an included file: its own text and lines, the same defaults and
    /// search folders.
    pub fn for_included_file(&self, file: &'a Path, text: &'a str) -> Ctx<'a> {
        self.for_included_file_with(file, text, self.defaults)
    }

    /// [`Self::for_included_file`] with the included file's own `defaults` (the
    /// including scene's plus those the included file adds).
    pub fn for_included_file_with(
        &self,
        file: &'a Path,
        text: &'a str,
        defaults: &'a HashMap<String, String>,
    ) -> Ctx<'a> {
        let child = Ctx::new(file, text, defaults)
            .with_plugin_names(self.canonical)
            .with_mode(self.mode);
        *child.search.borrow_mut() = self.search.borrow().clone();
        child.expanded.set(self.expanded.get());
        child
    }

    /// Takes back what an included file's context gathered: its warnings, mesh files,
    /// search folders and substitution budget.
    pub fn adopt(&self, child: Ctx) {
        for w in child.warnings.take() {
            if self.warnings.borrow().len() < MAX_WARNINGS {
                self.warnings.borrow_mut().push(w);
            }
        }
        self.warning_count
            .set(self.warning_count.get() + child.warning_count.get());
        self.mesh_files.borrow_mut().extend(child.mesh_files.take());
        *self.search.borrow_mut() = child.search.take();
        self.expanded.set(child.expanded.get());
    }

    /// Records a warning located at `node`. After [`MAX_WARNINGS`], further warnings are
    /// only counted (one summary line): a scene of a million silent emitters needs one
    /// screen, and finding a line number scans the text.
    pub fn warn(&self, node: Node, message: impl Into<String>) {
        let mut w = self.warnings.borrow_mut();
        if w.len() < MAX_WARNINGS {
            w.push(self.err(node, message).to_string());
        }
        drop(w);
        self.warning_count.set(self.warning_count.get() + 1);
    }

    /// The warnings, with a last line counting those not shown.
    /// Records a mesh file the scene reads.
    pub fn read_mesh_file(&self, path: &Path) {
        self.mesh_files.borrow_mut().push(path.to_path_buf());
    }

    /// The mesh files read, moved out.
    pub fn take_mesh_files(&self) -> Vec<std::path::PathBuf> {
        self.mesh_files.take()
    }

    pub fn take_warnings(&self) -> Vec<String> {
        let mut w = self.warnings.take();
        let more = self.warning_count.get().saturating_sub(w.len());
        if more > 0 {
            w.push(format!(
                "{}: {more} more warnings not shown",
                self.file.display()
            ));
        }
        w
    }

    pub fn line(&self, node: Node) -> u32 {
        let doc = node.document();
        doc.text_pos_at(node.range().start).row
    }

    pub fn describe(node: Node) -> String {
        let tag = node.tag_name().name();
        match (node.attribute("type"), node.attribute("name")) {
            (Some(t), _) => format!("{tag} type=\"{t}\""),
            (None, Some(n)) => format!("{tag} name=\"{n}\""),
            _ => tag.to_string(),
        }
    }

    pub fn err(&self, node: Node, message: impl Into<String>) -> SceneError {
        SceneError::new(self.file, self.line(node), Self::describe(node), message)
    }

    /// An attribute with `$name` references replaced by their defaults.
    /// An attribute with its `$default`s substituted. A plugin's `type` is matched
    /// without regard to case ("Rectangle" = "rectangle",
    /// `plugins::canonical_plugin_name`).
    pub fn attr(&self, node: Node, name: &str) -> Result<Option<String>, SceneError> {
        match node.attribute(name) {
            None => Ok(None),
            Some(raw) if name == "type" => self
                .substitute(node, raw)
                .map(|t| Some((self.canonical)(t))),
            Some(raw) => self.substitute(node, raw).map(Some),
        }
    }

    pub fn required_attr(&self, node: Node, name: &str) -> Result<String, SceneError> {
        self.attr(node, name)?
            .ok_or_else(|| self.err(node, format!("missing attribute '{name}'")))
    }

    fn substitute(&self, node: Node, raw: &str) -> Result<String, SceneError> {
        let mut out = String::with_capacity(raw.len());
        let mut rest = raw;
        while let Some(pos) = rest.find('$') {
            out.push_str(&rest[..pos]);
            let after = &rest[pos + 1..];
            let len = after
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(after.len());
            let key = &after[..len];
            match self.defaults.get(key) {
                Some(v) => {
                    if out.len() + v.len() > MAX_SUBSTITUTED_BYTES {
                        return Err(self.err(
                            node,
                            format!("'$' substitution makes an attribute longer than {MAX_SUBSTITUTED_BYTES} bytes"),
                        ));
                    }
                    out.push_str(v)
                }
                None => {
                    return Err(self.err(
                        node,
                        format!("'${key}' has no <default name=\"{key}\"> and no -D {key}=..."),
                    ))
                }
            }
            rest = &after[len..];
        }
        out.push_str(rest);
        let grown = self.expanded.get() + out.len().saturating_sub(raw.len());
        if grown > MAX_EXPANDED_BYTES {
            return Err(self.err(
                node,
                format!(
                    "'$' substitutions add more than {MAX_EXPANDED_BYTES} bytes to the document"
                ),
            ));
        }
        self.expanded.set(grown);
        Ok(out)
    }
}

/// The longest attribute value after `$name` substitution (real ones are a few hundred
/// bytes): defaults referenced many times must not expand a small file into gigabytes.
pub const MAX_SUBSTITUTED_BYTES: usize = 1 << 20;
/// The most that substitutions may add over the whole document.
pub const MAX_EXPANDED_BYTES: usize = 64 << 20;
