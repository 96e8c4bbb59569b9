//! The import graph stays layered (ARCHITECTURE.md, "Layers"): every module imports
//! only modules below it, and no two source files import each other, directly or round
//! a longer cycle. Read from the `use` lines and `crate::`/`super::` paths of `src/`,
//! leaving out each file's `#[cfg(test)]` tests (tests may use the whole crate).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers, bottom first. A module may import modules of lower layers only; modules
/// of one layer do not import each other.
const LAYERS: &[&[&str]] = &[
    &["math", "cpu", "io"],
    &["stats", "geometry", "polarization", "spectral"],
    &["textures", "sensors"],
    &["materials", "media"],
    &["lights"],
    &["scene"],
    &["render"],
    &["bundle"],
    &["denoise", "nlos"],
    &["report"],
    &["viz", "cluster"],
    &["job"],
    &["cli"],
];

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module path of a file: `src/scene/xml.rs` -> ["scene", "xml"], `src/scene/mod.rs`
/// -> ["scene"], `src/lib.rs` -> [].
fn module_of(file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src()).unwrap();
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

/// The code of a file without its unit tests (from `#[cfg(test)]` on) and comments.
fn code(file: &Path) -> String {
    let text = std::fs::read_to_string(file).unwrap();
    let body = match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => &text[..],
    };
    body.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Expands `a::{b, c::{d, e}}` into ["a::b", "a::c::d", "a::c::e"].
fn expand(tree: &str) -> Vec<String> {
    let tree: String = tree.chars().filter(|c| !c.is_whitespace()).collect();
    let Some(open) = tree.find('{').filter(|_| tree.ends_with('}')) else {
        return vec![tree];
    };
    let prefix = &tree[..open];
    let inner = &tree[open + 1..tree.len() - 1];
    let (mut depth, mut start, mut out) = (0, 0, Vec::new());
    for (i, ch) in inner.char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                out.extend(
                    expand(&inner[start..i])
                        .into_iter()
                        .map(|s| format!("{prefix}{s}")),
                );
                start = i + 1;
            }
            _ => {}
        }
    }
    if start < inner.len() {
        out.extend(
            expand(&inner[start..])
                .into_iter()
                .map(|s| format!("{prefix}{s}")),
        );
    }
    out
}

/// Every path a file names that starts with `crate::`, `super::` or `self::`, as an
/// absolute module path.
fn paths(file: &Path, code: &str) -> Vec<Vec<String>> {
    let here = module_of(file);
    let is_mod = matches!(
        file.file_name().unwrap().to_str().unwrap(),
        "mod.rs" | "lib.rs" | "main.rs"
    );
    // `super` of a file module is its folder's module; of a mod.rs, the folder's parent.
    let parent: Vec<String> = if is_mod {
        here[..here.len().saturating_sub(1)].to_vec()
    } else {
        here[..here.len() - 1].to_vec()
    };
    let mut raw = Vec::new();
    let mut rest = code;
    while let Some(i) = rest.find("use ") {
        let before = rest[..i].chars().last();
        let stmt_end = rest[i..].find(';').map_or(rest.len(), |e| i + e);
        if before.is_none_or(|c| !c.is_alphanumeric() && c != '_') {
            raw.extend(expand(&rest[i + 4..stmt_end]));
        }
        rest = &rest[(i + 4).min(rest.len())..];
    }
    for key in ["crate::", "super::"] {
        let mut at = 0;
        while let Some(i) = code[at..].find(key) {
            let s = at + i;
            let end = code[s..]
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .map_or(code.len(), |e| s + e);
            raw.push(code[s..end].to_string());
            at = end;
        }
    }
    let mut out = Vec::new();
    for p in raw {
        let parts: Vec<&str> = p.split("::").filter(|s| !s.is_empty()).collect();
        let (base, tail) = match parts.first() {
            Some(&"crate") => (Vec::new(), &parts[1..]),
            Some(&"super") => (parent.clone(), &parts[1..]),
            Some(&"self") => (here.clone(), &parts[1..]),
            _ => continue,
        };
        let mut full = base;
        full.extend(tail.iter().map(|s| s.to_string()));
        out.push(full);
    }
    out
}

/// The source file a module path lands in: the longest prefix that is a file.
fn file_of(path: &[String]) -> Option<PathBuf> {
    for n in (1..=path.len()).rev() {
        let dir = path[..n].iter().fold(src(), |d, p| d.join(p));
        let file = dir.with_extension("rs");
        if file.is_file() {
            return Some(file);
        }
        if dir.join("mod.rs").is_file() {
            return Some(dir.join("mod.rs"));
        }
    }
    None
}

fn graph() -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut g = BTreeMap::new();
    for f in files {
        let code = code(&f);
        let targets: BTreeSet<PathBuf> = paths(&f, &code)
            .iter()
            .filter_map(|p| file_of(p))
            .filter(|t| *t != f)
            .collect();
        g.insert(f, targets);
    }
    g
}

fn top(file: &Path) -> String {
    module_of(file).first().cloned().unwrap_or_default()
}

fn rel(p: &Path) -> String {
    p.strip_prefix(src()).unwrap().display().to_string()
}

#[test]
fn every_module_imports_only_layers_below_it() {
    let mut wrong = Vec::new();
    for (f, targets) in graph() {
        let from = top(&f);
        if matches!(from.as_str(), "" | "main") {
            continue;
        }
        let Some(lf) = layer(&from) else {
            wrong.push(format!("{}: module `{from}` is in no layer", rel(&f)));
            continue;
        };
        for t in targets {
            let to = top(&t);
            if to == from || to.is_empty() {
                continue;
            }
            match layer(&to) {
                Some(lt) if lt < lf => {}
                _ => wrong.push(format!(
                    "{} -> {} ({from} may not import {to})",
                    rel(&f),
                    rel(&t)
                )),
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports against the layers:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_two_files_import_each_other() {
    // A folder's mod.rs declares its files and re-exports their names: edges to and
    // from it are the module's structure, not a dependency between files.
    let is_mod = |p: &Path| {
        p.file_name()
            .is_some_and(|n| n == "mod.rs" || n == "lib.rs")
    };
    let g: BTreeMap<PathBuf, Vec<PathBuf>> = graph()
        .into_iter()
        .filter(|(f, _)| !is_mod(f))
        .map(|(f, t)| (f, t.into_iter().filter(|t| !is_mod(t)).collect()))
        .collect();
    // Tarjan's strongly connected components: any with two or more files is a cycle.
    struct T<'a> {
        g: &'a BTreeMap<PathBuf, Vec<PathBuf>>,
        index: BTreeMap<&'a PathBuf, usize>,
        low: BTreeMap<&'a PathBuf, usize>,
        stack: Vec<&'a PathBuf>,
        on: BTreeSet<&'a PathBuf>,
        cycles: Vec<Vec<String>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a PathBuf) {
        let i = t.index.len();
        t.index.insert(v, i);
        t.low.insert(v, i);
        t.stack.push(v);
        t.on.insert(v);
        for w in t.g.get(v).into_iter().flatten() {
            if !t.g.contains_key(w) {
                continue;
            }
            if !t.index.contains_key(w) {
                visit(t, w);
                let lw = t.low[w];
                let lv = t.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if t.on.contains(w) {
                let iw = t.index[w];
                let lv = t.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = t.stack.pop().unwrap();
                t.on.remove(w);
                comp.push(rel(w));
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.cycles.push(comp);
            }
        }
    }
    let mut t = T {
        g: &g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        cycles: Vec::new(),
    };
    for v in g.keys() {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    let msg: Vec<String> = t.cycles.iter().map(|c| c.join(" <-> ")).collect();
    assert!(
        msg.is_empty(),
        "files importing each other:\n{}",
        msg.join("\n")
    );
}

/// The checker itself: a planted upward import and a planted cycle are found.
#[test]
fn the_checker_sees_group_imports_and_relative_paths() {
    assert_eq!(
        expand("a::{b, c::{d, e}}"),
        vec!["a::b".to_string(), "a::c::d".into(), "a::c::e".into()]
    );
    let xml = src().join("scene").join("xml.rs");
    let p = paths(
        &xml,
        "use super::{props::Ctx, Scene};\nlet x = crate::render::cpu::X;",
    );
    let want: Vec<Vec<String>> = vec![
        vec!["scene".into(), "props".into(), "Ctx".into()],
        vec!["scene".into(), "Scene".into()],
        vec!["render".into(), "cpu".into(), "X".into()],
    ];
    for w in &want {
        assert!(p.contains(w), "{w:?} not in {p:?}");
    }
    assert_eq!(
        file_of(&["scene".into(), "props".into(), "Ctx".into()]),
        Some(src().join("scene").join("props.rs"))
    );
    assert_eq!(
        file_of(&["scene".into(), "Scene".into()]),
        Some(src().join("scene").join("mod.rs"))
    );
    assert!(layer("render") > layer("geometry"));
}
