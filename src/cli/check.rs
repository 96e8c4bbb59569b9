//! `tstat check SCENE.xml...`: lists every unsupported feature of each scene at once
//! (file:line), or says "ok" for scenes that would render. Exit status 1 if any scene
//! would not.

use super::render::ModeArg;
use crate::scene::check::{check_in_mode, Verdict};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Mitsuba 3 XML scenes.
    #[arg(required = true)]
    pub scenes: Vec<PathBuf>,
    /// Set a scene parameter: -D name=value (repeatable).
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    pub defines: Vec<String>,
    /// Add a folder to the search path for the files the scenes name, after each
    /// scene's own folder (Mitsuba's -a; repeatable).
    #[arg(short = 'a', value_name = "DIR")]
    pub search_paths: Vec<PathBuf>,
    /// The render mode the scenes are loaded for, as `render --mode` (what a mode
    /// does not model, or a blackbody spectrum outside the spectral mode, is an error).
    #[arg(long, value_enum, default_value_t = ModeArg::Rgb)]
    pub mode: ModeArg,
}

pub fn run(a: CheckArgs) -> anyhow::Result<()> {
    let mut defaults = Vec::new();
    for d in &a.defines {
        let Some((k, v)) = d.split_once('=') else {
            anyhow::bail!("-D {d}: expected name=value");
        };
        anyhow::ensure!(!k.trim().is_empty(), "-D {d}: the name is empty");
        defaults.push((k.trim().to_string(), v.to_string()));
    }
    let search = super::util::search_folders(&a.search_paths)?;
    let mut bad = 0;
    for scene in &a.scenes {
        match check_in_mode(scene, &defaults, &search, a.mode.into()) {
            Verdict::Ok(notes) => {
                say!("{}: ok", scene.display());
                for n in notes {
                    say!("  note: {n}");
                }
            }
            Verdict::Unsupported(found) => {
                bad += 1;
                say!("{}: {} unsupported:", scene.display(), found.len());
                for f in found {
                    say!("  {f}");
                }
            }
            Verdict::Fails(e) => {
                bad += 1;
                say!("{}: does not load:\n  {e}", scene.display());
            }
        }
    }
    if bad > 0 {
        anyhow::bail!("{bad} of {} scenes would not render", a.scenes.len());
    }
    Ok(())
}
