//! Recipes for running one render job's shards on an existing scheduler (SPEC 12):
//! a Slurm array job and a Kubernetes indexed Job, each followed by a merge. The
//! recipes only call `tstat render ... --shard auto/N` and `tstat merge`; the
//! scheduler does the rest. `slurm.rs` and `k8s.rs` write the text; `tstat cluster`
//! (cli/cluster.rs) checks the scene and options first.

pub mod k8s;
pub mod slurm;

use std::path::PathBuf;

/// Errors of the recipes' options: what cannot go into a Slurm or Kubernetes recipe.
/// `what` names the option or path ("--out", "the scene").
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ClusterError {
    #[error("--time {value}: {reason}")]
    Time { value: String, reason: &'static str },
    #[error("--partition {0:?}: not a Slurm partition name")]
    Partition(String),
    #[error("{what} {}: not UTF-8", .path.display())]
    NotUtf8 { what: String, path: PathBuf },
    /// A character the recipes cannot carry; `directive`: the path goes into an
    /// `#SBATCH` line.
    #[error("{what} {path:?}: the character {c:?} cannot go into the recipes{}", directive_note(.directive))]
    Character {
        what: String,
        path: String,
        c: char,
        directive: bool,
    },
    /// An option's value that cannot go into a recipe, and why.
    #[error("{what} {}: {reason}", .value.escape_debug())]
    Value {
        what: &'static str,
        value: String,
        reason: &'static str,
    },
    #[error("{what} {} is not under the volume's mount point {mount} (--mount): the pods could not see it", .path.display())]
    NotUnderMount {
        what: String,
        path: PathBuf,
        mount: String,
    },
}

fn directive_note(directive: &bool) -> &'static str {
    if *directive {
        " (Slurm directive lines take no spaces, quotes, %, \\ or #)"
    } else {
        " (no control characters or line breaks)"
    }
}

/// What both recipes need.
#[derive(Clone, Debug)]
pub struct Job {
    /// The tstat binary (absolute for Slurm; a name on the image's PATH for Kubernetes).
    pub binary: String,
    /// Absolute scene path.
    pub scene: PathBuf,
    /// Absolute output folder: shards in `DIR/shards`, logs in `DIR/logs`, the merged
    /// bundle `DIR/merged.tstats`.
    pub dir: PathBuf,
    pub shards: u64,
    /// Render options passed through (already checked by parsing them as `render`'s).
    pub render_options: Vec<String>,
    /// Also denoise the merged bundle into `DIR/denoised.npy`.
    pub denoise: bool,
    /// Resources of one task.
    pub cpus: u32,
    /// Memory of one render task and of the merge task, in MiB.
    pub render_mib: u64,
    pub merge_mib: u64,
    /// The merge's and the denoiser's `--max-memory` in MiB (the merge task's memory
    /// less the per-pixel images and a margin).
    pub band_mib: u64,
}

/// The variable the Slurm render task takes its threads from.
pub const SLURM_THREADS: &str = "${SLURM_CPUS_PER_TASK:-1}";

impl Job {
    /// `DIR/shards/shard-{shard}.tstats`: each task's output (tstat fills in the index).
    pub fn shard_pattern(&self) -> PathBuf {
        self.dir.join("shards").join("shard-{shard}.tstats")
    }

    pub fn merged(&self) -> PathBuf {
        self.dir.join("merged.tstats")
    }

    pub fn denoised(&self) -> PathBuf {
        self.dir.join("denoised.npy")
    }

    /// The render command of every task, as arguments.
    pub fn render_args(&self, threads: &str) -> Vec<String> {
        let mut v = vec![
            self.binary.clone(),
            "render".into(),
            self.scene.display().to_string(),
            "--shard".into(),
            format!("auto/{}", self.shards),
            "--out".into(),
            self.shard_pattern().display().to_string(),
            "--threads".into(),
            threads.into(),
        ];
        v.extend(self.render_options.iter().cloned());
        v
    }
}

/// The merge task's shell commands (POSIX sh): the merge of every shard (the glob left
/// to the shell), then with `denoise` the denoiser with `threads` (a number or a
/// variable the shell expands, double-quoted).
pub fn merge_commands(job: &Job, threads: &str) -> Vec<String> {
    let b = quote(&job.binary);
    // The folder quoted, the glob after it left to the shell.
    let mut v = vec![format!(
        "{b} merge {}/shard-*.tstats --out {} --max-memory {}Mi",
        quote_path(&job.dir.join("shards")),
        quote_path(&job.merged()),
        job.band_mib
    )];
    if job.denoise {
        v.push(format!(
            "{b} denoise {} --out {} --threads \"{threads}\" --max-memory {}Mi",
            quote_path(&job.merged()),
            quote_path(&job.denoised()),
            job.band_mib
        ));
    }
    v
}

/// `path` with `.` and `..` resolved lexically (no file system access; the path may
/// not exist yet), so that prefix checks see where it really points.
pub fn normalize(path: &std::path::Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// Whether `c` cannot go into a recipe at all: a control character (newline, tab,
/// escape, ...) or a Unicode line or paragraph separator. A newline would end an
/// `#SBATCH` directive or a comment line, and a quoted word spanning lines is legal
/// shell but unreadable in the printed commands, so these are refused everywhere.
pub fn unprintable(c: char) -> bool {
    c.is_control() || matches!(c, '\u{2028}' | '\u{2029}')
}

/// Refuses a path the recipes cannot carry safely: non-UTF-8 and [`unprintable`]
/// characters always, and for paths in `#SBATCH` lines (`directive`) also whitespace,
/// quotes, `%`, `\` and `#` (Slurm reads a directive's value up to whitespace or `#`,
/// takes `%` as a file name pattern, `"` as a quote and `\` as its escape). Every other character (`$`, backticks,
/// `;`, `*`, `~`, ...) is allowed: the recipes and the printed commands quote every
/// path with [`quote`].
pub fn check_path(path: &std::path::Path, what: &str, directive: bool) -> Result<(), ClusterError> {
    let s = path.to_str().ok_or_else(|| ClusterError::NotUtf8 {
        what: what.to_string(),
        path: path.to_path_buf(),
    })?;
    check_text(s, what, directive)
}

/// [`check_path`] for any text going into the recipes (an option's value).
pub fn check_text(s: &str, what: &str, directive: bool) -> Result<(), ClusterError> {
    let bad =
        |c: char| unprintable(c) || (directive && (c.is_whitespace() || "%\"'\\#".contains(c)));
    match s.chars().find(|&c| bad(c)) {
        Some(c) => Err(ClusterError::Character {
            what: what.to_string(),
            path: s.to_string(),
            c,
            directive,
        }),
        None => Ok(()),
    }
}

/// Whether `s` reads the same unquoted in a POSIX shell, wherever it stands: ASCII
/// letters, digits and `/._-+:,@%=`, not starting with `=` or `%`, and not an
/// assignment when it stands first (`NAME=...`).
fn plain_word(s: &str) -> bool {
    let chars = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+:,@%=".contains(c));
    let assignment = s.split_once('=').is_some_and(|(name, _)| {
        name.chars().next().is_some_and(|c| !c.is_ascii_digit())
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
    });
    // zsh expands a leading `=` (the path of a command); interactive bash takes a
    // command `%1` as `fg %1`.
    chars && !assignment && !s.starts_with(['=', '%'])
}

/// One word for a POSIX shell (sh, bash, dash, zsh in sh mode): `s` itself when it is
/// plain (letters, digits and `/._-+:,@%=`; readable), else single-quoted with each `'`
/// written `'\''`. Inside single quotes nothing is special, so the shell reads back
/// exactly `s` (any bytes but NUL, which no argument can hold). Every path and argument
/// `tstat cluster` writes into a script or prints as a command goes through here. A
/// leading `-` is left to the program that reads the word (the recipes' paths are
/// absolute, so none starts with `-`).
pub fn quote(s: &str) -> String {
    if plain_word(s) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// A command line of quoted words.
pub fn command_line<S: AsRef<str>>(words: &[S]) -> String {
    words
        .iter()
        .map(|w| quote(w.as_ref()))
        .collect::<Vec<_>>()
        .join(" ")
}

/// [`quote`] of a path (the recipes' paths are checked UTF-8).
pub fn quote_path(p: &std::path::Path) -> String {
    quote(&p.to_string_lossy())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_normalized_and_checked() {
        use std::path::Path;
        assert_eq!(
            normalize(Path::new("/data/../scratch/./x")),
            Path::new("/scratch/x")
        );
        assert_eq!(normalize(Path::new("/a/b/../../..")), Path::new("/"));
        let refused = |path: &str, what: &str, c: char, directive: bool| {
            assert_eq!(
                check_path(Path::new(path), what, directive),
                Err(ClusterError::Character {
                    what: what.to_string(),
                    path: path.to_string(),
                    c,
                    directive,
                }),
                "{path:?}"
            );
        };
        refused("/scratch/run 1", "--out", ' ', true);
        refused("/scratch/run%j", "--out", '%', true);
        assert!(check_path(Path::new("/scratch/run 1"), "the scene", false).is_ok());
        refused("/scratch/a\nb", "the scene", '\n', false);
    }

    /// The shells to check against: POSIX sh (dash here) and bash, where present.
    fn shells() -> Vec<&'static str> {
        ["sh", "bash"]
            .into_iter()
            .filter(|sh| {
                std::process::Command::new(sh)
                    .args(["-c", ":"])
                    .output()
                    .is_ok_and(|o| o.status.success())
            })
            .collect()
    }

    /// What `shell` prints for `printf %s WORDS`: the words joined by the shell's
    /// argument splitting, each printed back to back.
    fn printed(shell: &str, words: &str) -> Vec<u8> {
        let out = std::process::Command::new(shell)
            .arg("-c")
            .arg(format!("printf %s {words}"))
            .env("LC_ALL", "C.UTF-8")
            .output()
            .expect("run the shell");
        assert!(
            out.status.success(),
            "{shell} -c 'printf %s {words}': {}",
            String::from_utf8_lossy(&out.stderr)
        );
        out.stdout
    }

    /// A reference reader of the words `quote` writes: plain characters, and
    /// single-quoted runs with `\'` between them. Returns the word, or `None` when the
    /// text holds anything else (a character a shell would treat specially).
    fn read_word(q: &str) -> Option<String> {
        let mut out = String::new();
        let mut it = q.chars().peekable();
        while let Some(c) = it.next() {
            match c {
                '\'' => loop {
                    match it.next()? {
                        '\'' => break,
                        c => out.push(c),
                    }
                },
                '\\' => out.push(it.next().filter(|&c| c == '\'')?),
                c if c.is_ascii_alphanumeric() || "/._-+:,@%=".contains(c) => out.push(c),
                _ => return None,
            }
        }
        (!q.is_empty()).then_some(out)
    }

    const HOSTILE: &[&str] = &[
        "plain/path.xml",
        "a b",
        "it's",
        "''",
        "'\\''",
        "{shard}",
        "$HOME",
        "$(touch x)",
        "d$(touch${IFS}x)",
        "`touch x`",
        "a;touch x",
        "a&&b||c|d&",
        "x\"y",
        "\"$(id)\"",
        "a\nb",
        "a\tb\r",
        "\\",
        "\\'",
        "-rf",
        "--out=x",
        "~",
        "~root/x",
        "a~b",
        "*",
        "/tmp/*.tstats",
        "[a]",
        "?",
        "#comment",
        "a#b",
        "!x",
        "=ls",
        "%1",
        "A=b",
        "_x=1",
        "PATH=/x",
        "1x=y",
        "<in",
        ">out",
        "(sub)",
        "{a,b}",
        "éé ü/雪/🦀",
        "\u{2028}",
        "",
        " ",
    ];

    #[test]
    fn quoting_survives_posix_shells() {
        for s in HOSTILE {
            let q = quote(s);
            assert_eq!(read_word(&q).as_deref(), Some(*s), "{s:?} -> {q}");
            for sh in shells() {
                assert_eq!(printed(sh, &q), s.as_bytes(), "{sh}: {s:?} -> {q}");
            }
        }
        // Several words on one line stay separate words.
        let line = command_line(HOSTILE);
        for sh in shells() {
            let out = std::process::Command::new(sh)
                .arg("-c")
                .arg(format!("for a in {line}; do printf '%s\\0' \"$a\"; done"))
                .output()
                .unwrap();
            let got: Vec<&[u8]> = out.stdout.split(|&b| b == 0).collect();
            let want: Vec<&[u8]> = HOSTILE
                .iter()
                .map(|s| s.as_bytes())
                .chain([&b""[..]])
                .collect();
            assert_eq!(got, want, "{sh}: {line}");
        }
    }

    #[test]
    fn plain_words_stay_readable_and_assignments_are_quoted() {
        for s in [
            "/scratch/run1/render.sbatch",
            "--spp",
            "4096",
            "auto/16",
            "-D",
            "--for=condition=complete",
            "job/x-render",
            "a:b,c@d+e%f",
        ] {
            assert_eq!(quote(s), *s);
        }
        for (s, q) in [
            ("A=b", "'A=b'"),
            ("=x", "'=x'"),
            ("%1", "'%1'"),
            ("it's", r"'it'\''s'"),
            ("", "''"),
            ("~", "'~'"),
        ] {
            assert_eq!(quote(s), q);
        }
        // In command position a quoted `A=b` is a command name, not an assignment.
        for sh in shells() {
            let out = std::process::Command::new(sh)
                .arg("-c")
                .arg(format!("{} 2>/dev/null; echo $?", quote("A=b")))
                .output()
                .unwrap();
            assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), "127", "{sh}");
        }
    }

    mod prop {
        use super::*;
        use proptest::prelude::*;

        /// Strings of any characters but NUL, weighted towards the ones shells treat
        /// specially.
        fn hostile_string() -> impl Strategy<Value = String> {
            let special = proptest::sample::select(
                "'\"\\$`;&|<>(){}[]*?~#!= \t\n%-/.^@:,+"
                    .chars()
                    .collect::<Vec<_>>(),
            );
            let any = any::<char>().prop_filter("no NUL", |&c| c != '\0');
            let byte = (1u8..=255).prop_map(char::from);
            proptest::collection::vec(prop_oneof![3 => special, 2 => byte, 1 => any], 0..24)
                .prop_map(|v| v.into_iter().collect())
        }

        proptest! {
            #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

            #[test]
            fn quote_round_trips(s in hostile_string()) {
                let q = quote(&s);
                prop_assert_eq!(read_word(&q), Some(s.clone()), "{:?} -> {}", s, q);
                for sh in shells() {
                    prop_assert_eq!(printed(sh, &q), s.as_bytes().to_vec(), "{}: {:?} -> {}", sh, s, q);
                }
            }
        }
    }
}
