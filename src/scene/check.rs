//! `tstat check`: every unsupported feature of a scene at once, for users porting
//! scenes. A static scan of the scene file and its includes lists each plugin, element
//! or integrator tstat does not support, with file:line; a scene with none is then
//! loaded for real (tiny film), which catches parameter-level problems (the first
//! error), or says it would render.
//!
//! The lists below name what the loaders accept; `tests/it/scene_compat.rs` checks that
//! every scene in `scenes/` scans clean and that each listed plugin kind loads.

use super::ctx::Ctx;
use super::plugins::{canonical_plugin_name, SUPPORTED};
use super::{Overrides, Scene};
use roxmltree::Node;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Elements with no support at all (whatever their type).
const UNSUPPORTED_TAGS: &[(&str, &str)] = &[];

/// One unsupported feature.
#[derive(Clone, Debug, PartialEq)]
pub struct Finding {
    pub file: PathBuf,
    pub line: u32,
    pub what: String,
}

impl std::fmt::Display for Finding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.file.display(), self.line, self.what)
    }
}

/// The outcome for one scene.
pub enum Verdict {
    /// Loads: it would render; with notes on what a user comparing renderers should
    /// know (the time origin's shift).
    Ok(Vec<String>),
    /// The unsupported features found by the scan (none missed by it: then the
    /// loader's first error).
    Unsupported(Vec<Finding>),
    /// The scan found nothing, but the scene does not load (a parameter, a file...).
    Fails(String),
}

/// Checks one scene (`defaults` as `-D`) for the RGB mode.
/// `search`: the `-a` folders (see [`Overrides::search_paths`]).
pub fn check(path: &Path, defaults: &[(String, String)], search: &[PathBuf]) -> Verdict {
    check_in_mode(path, defaults, search, super::mode::RenderMode::Rgb)
}

/// [`check`], the scene loaded for `mode` (`tstat check --mode`).
pub fn check_in_mode(
    path: &Path,
    defaults: &[(String, String)],
    search: &[PathBuf],
    mode: super::mode::RenderMode,
) -> Verdict {
    let mut findings = Vec::new();
    let defaults_map: HashMap<String, String> = defaults.iter().cloned().collect();
    scan_file(
        path,
        None,
        &defaults_map,
        search,
        &mut findings,
        &mut Vec::new(),
    );
    if !findings.is_empty() {
        return Verdict::Unsupported(findings);
    }
    let overrides = Overrides {
        width: Some(4),
        height: Some(4),
        spp: Some(2),
        bins: Some(2),
        defaults: defaults.to_vec(),
        search_paths: search.to_vec(),
        mode,
        ..Default::default()
    };
    match Scene::load(path, &overrides) {
        Ok(scene) => Verdict::Ok(time_origin_note(&scene).into_iter().collect()),
        Err(e) => Verdict::Fails(e.to_string()),
    }
}

/// Says how far the default time origin (the near-clip plane) moves arrivals from the
/// pinhole origin when that is more than a tenth of a bin.
fn time_origin_note(scene: &Scene) -> Option<String> {
    let [lo, hi] = scene.camera.near_offsets()?;
    let h = scene.film.time.bin_width_opl;
    (hi > 0.1 * h).then(|| {
        let span = if hi - lo > 1e-9 * hi {
            format!("{lo:.4}..{hi:.4} OPL ({:.2}..{:.2} bins)", lo / h, hi / h)
        } else {
            format!("{lo:.4} OPL ({:.2} bins)", lo / h)
        };
        format!(
            "time origin: OPL counts from the near-clip plane (as mitransient), so arrivals are {span} earlier than counted from the camera (--time-origin pinhole)"
        )
    })
}

/// Scans one file (and the files it includes); problems reading or parsing a file
/// are findings too.
/// `parent`: the including file's context, whose search folders an included file
/// inherits (as the real load does).
fn scan_file(
    path: &Path,
    parent: Option<&Ctx>,
    defaults: &HashMap<String, String>,
    search: &[PathBuf],
    out: &mut Vec<Finding>,
    stack: &mut Vec<PathBuf>,
) {
    let here = |line: u32, what: String| Finding {
        file: path.to_path_buf(),
        line,
        what,
    };
    let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
    if stack.contains(&canonical) || stack.len() > 16 {
        out.push(here(0, "included recursively".into()));
        return;
    }
    let text = match crate::io::read_regular(path, crate::io::MAX_SCENE_BYTES)
        .map_err(|e| e.to_string())
        .and_then(|b| String::from_utf8(b).map_err(|_| "not UTF-8".to_string()))
    {
        Ok(t) => t,
        Err(e) => {
            out.push(here(0, format!("cannot read: {e}")));
            return;
        }
    };
    let options = roxmltree::ParsingOptions {
        nodes_limit: super::limits::MAX_NODES,
        ..Default::default()
    };
    let doc = match roxmltree::Document::parse_with_options(&text, options) {
        Ok(d) => d,
        Err(e) => {
            out.push(here(e.pos().row, super::xml::malformed(&e)));
            return;
        }
    };
    let ctx = match parent {
        Some(p) => p.for_included_file(path, &text),
        None => Ctx::new(path, &text, defaults)
            .with_plugin_names(canonical_plugin_name)
            .with_search_paths(search),
    };
    stack.push(canonical);
    for node in doc.root_element().descendants().filter(|n| n.is_element()) {
        scan_element(&ctx, node, defaults, out, stack);
    }
    stack.pop();
}

fn scan_element(
    ctx: &Ctx,
    node: Node,
    defaults: &HashMap<String, String>,
    out: &mut Vec<Finding>,
    stack: &mut Vec<PathBuf>,
) {
    let tag = node.tag_name().name();
    let line = ctx.line(node);
    let mut push = |what: String| {
        out.push(Finding {
            file: ctx.file.to_path_buf(),
            line,
            what,
        })
    };
    if let Some((_, why)) = UNSUPPORTED_TAGS.iter().find(|(t, _)| *t == tag) {
        push(format!("<{tag}>: {why}"));
        return;
    }
    if tag == "include" {
        match ctx.attr(node, "filename") {
            Ok(Some(name)) => scan_file(
                &ctx.resolve_near(&name),
                Some(ctx),
                defaults,
                &[],
                out,
                stack,
            ),
            _ => push("<include> without a readable filename".into()),
        }
        return;
    }
    if tag == "path" {
        if let Ok(Some(v)) = ctx.attr(node, "value") {
            let dir = ctx.dir().join(&v);
            if dir.is_dir() {
                ctx.prepend_search_path(dir);
            }
        }
        return;
    }
    let Some((_, types)) = SUPPORTED.iter().find(|(t, _)| *t == tag) else {
        return;
    };
    // `$name` types are substituted from defaults; unknown ones are the loader's error.
    let Ok(Some(kind)) = ctx.attr(node, "type") else {
        return;
    };
    if !types.contains(&kind.as_str()) {
        push(format!(
            "<{tag} type=\"{kind}\">: not supported (supported: {})",
            types.join(", ")
        ));
    } else if tag == "emitter"
        && (kind == "area" || kind == "angulararea")
        && node
            .parent_element()
            .is_some_and(|p| !p.has_tag_name("shape") && !p.has_tag_name("scene"))
    {
        push(format!(
            "<emitter type=\"{kind}\"> must be in a <shape> or at the top level"
        ));
    } else if tag == "emitter"
        && (kind == "point" || kind == "projector")
        && node
            .parent_element()
            .is_some_and(|p| p.has_tag_name("shape"))
    {
        push(format!(
            "<emitter type=\"{kind}\"> cannot be attached to a shape"
        ));
    }
}
