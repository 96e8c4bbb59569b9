//! `tstat cluster slurm|k8s SCENE --shards N --out DIR [options] -- [render options]`:
//! writes the recipes of `crate::cluster` after checking, here, everything a task would
//! otherwise find out on the cluster: the render options (parsed as `render`'s), the
//! scene (loaded), the split of spp and replicates over the shards, and the memory a
//! task needs (the render's own estimate at the task's threads). Everything is checked
//! before anything is created or printed; the recipes are written under temporary
//! names and renamed into place, and a failure removes whatever this run created
//! ([`Staged`]). Every path and argument in what is written or printed is quoted by
//! `crate::cluster::quote`.

use super::render::RenderArgs;
use super::util::{arg, check_collisions, human_bytes, int_flag, size_flag, size_flag_in, Arg};
use crate::bundle::shard::Shard;
use crate::bundle::write::bundle_bytes_with;
use crate::cluster::{check_path, check_text, k8s, normalize, quote_path, slurm, Job};
use crate::render::{RenderSettings, StreamingMemory};
use crate::scene::Scene;
use anyhow::{anyhow, bail, Context};
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct ClusterArgs {
    #[command(subcommand)]
    pub scheduler: Scheduler,
}

#[derive(Subcommand, Debug)]
pub enum Scheduler {
    /// Slurm: DIR/render.sbatch (an array job of N tasks) and DIR/merge.sbatch. Submit
    /// `sbatch DIR/render.sbatch`, then `sbatch --dependency=afterok:<job id>
    /// DIR/merge.sbatch`.
    Slurm(SlurmArgs),
    /// Kubernetes: DIR/render-job.json (an indexed Job of N completions) and
    /// DIR/merge-job.json. `kubectl apply -f` the first, wait for it to complete, then
    /// apply the second.
    K8s(K8sArgs),
}

/// What both schedulers take.
#[derive(Args, Debug)]
pub struct Common {
    /// Mitsuba 3 XML scene.
    pub scene: PathBuf,
    /// Number of shards N (at least 2; at most 4,000,000 for Slurm, 100,000 for
    /// Kubernetes): each renders spp / N samples per pixel.
    #[arg(long, allow_negative_numbers = true)]
    pub shards: i64,
    /// Output folder (created): the recipes, shards/, logs/, then merged.tstats.
    #[arg(long)]
    pub out: PathBuf,
    /// CPUs of one task (its render threads), 1 to 1024.
    #[arg(long, default_value_t = 4, allow_negative_numbers = true)]
    pub cpus: i64,
    /// Memory of one render task, 64Mi to 1Pi (e.g. 4Gi; 4G is 4e9 bytes; default:
    /// twice the render's own estimate at --cpus threads, at least 1Gi).
    #[arg(long, allow_hyphen_values = true)]
    pub mem: Option<String>,
    /// Memory of the merge (and denoise) task, at most 1Pi; the merge's per-pixel images
    /// take about 160 bytes a pixel plus 64Mi, its bands and the denoiser the rest.
    #[arg(long, default_value = "2Gi", allow_hyphen_values = true)]
    pub merge_mem: String,
    /// Also denoise the merged bundle into DIR/denoised.npy.
    #[arg(long)]
    pub denoise: bool,
    /// Replace recipes already in DIR (never the shards or the merged bundle of an
    /// earlier run: the tasks would refuse to replace them).
    #[arg(long)]
    pub force: bool,
    /// Options for `tstat render`, after `--` (e.g. -- --spp 4096 --seed 7). Not
    /// --out, --shard or --threads: the recipe sets those.
    #[arg(last = true, allow_hyphen_values = true)]
    pub render_options: Vec<String>,
}

#[derive(Args, Debug)]
pub struct SlurmArgs {
    #[command(flatten)]
    pub common: Common,
    /// Time limit of each task (Slurm's format: minutes, M:S, H:M:S, D-H, D-H:M or
    /// D-H:M:S; above 0, at most 365 days).
    #[arg(long, default_value = "02:00:00", allow_hyphen_values = true)]
    pub time: String,
    /// Partition to submit to (default: the cluster's default).
    #[arg(long)]
    pub partition: Option<String>,
}

#[derive(Args, Debug)]
pub struct K8sArgs {
    #[command(flatten)]
    pub common: Common,
    /// Container image holding the tstat binary.
    #[arg(long)]
    pub image: String,
    /// Persistent volume claim the pods share (scene and output live on it).
    #[arg(long)]
    pub claim: String,
    /// Where the claim is mounted in the pods; the scene and --out must lie under it
    /// (at the same absolute paths as here).
    #[arg(long)]
    pub mount: String,
    /// The tstat binary inside the image.
    #[arg(long, default_value = "tstat")]
    pub binary: String,
    /// Pods running at once (default: every shard; at least 1).
    #[arg(long, allow_negative_numbers = true)]
    pub parallelism: Option<i64>,
    /// Job name prefix (default: from the scene's file name).
    #[arg(long)]
    pub name: Option<String>,
}

/// The most shards of a Slurm recipe: an array of N tasks needs Slurm's MaxArraySize
/// above N - 1, and Slurm takes at most 4,000,001.
pub const MAX_SLURM_SHARDS: u64 = 4_000_000;
/// The largest task memory (`--mem`, `--merge-mem`): 1 PiB, far beyond any node.
const MAX_TASK_MEMORY: (u64, &str) = (1 << 50, "1Pi");
/// The smallest render task memory.
const MIN_RENDER_MEMORY: (u64, &str) = (64 << 20, "64Mi");

/// Parses the render options as `tstat render SCENE --out X --shard 0/N ...` would.
fn render_args(c: &Common, shards: u64) -> anyhow::Result<RenderArgs> {
    for o in &c.render_options {
        let flag = o.split('=').next().unwrap_or(o);
        if ["--out", "--shard", "--threads"].contains(&flag) {
            bail!("{flag} among the render options: the recipe sets it (shards go to DIR/shards, threads are --cpus)");
        }
    }
    let scene = c.scene.as_os_str().to_os_string();
    let mut argv: Vec<std::ffi::OsString> = ["tstat", "render"].map(Into::into).to_vec();
    argv.push(scene);
    argv.extend(["--out", "x", "--shard"].map(Into::into));
    argv.push(format!("0/{shards}").into());
    argv.extend(c.render_options.iter().map(Into::into));
    match super::Cli::try_parse_from(argv) {
        Ok(super::Cli {
            command: super::Command::Render(r),
        }) => Ok(r),
        Ok(_) => bail!("the render options do not parse as tstat render's"),
        Err(e) => Err(anyhow!(
            "the render options do not parse as tstat render's: {}",
            e.to_string().lines().next().unwrap_or_default()
        )),
    }
}

/// A checked job: the recipe's description, the line that describes it (printed once
/// the recipes are written), and the inputs no output may replace.
struct Plan {
    job: Job,
    summary: String,
    inputs: Vec<Arg>,
    /// The search folders (`-a`, absolute) the tasks will read.
    search_folders: Vec<PathBuf>,
}

/// Checks the job and makes its description (numbers, sizes, render options, paths,
/// the scene loaded, shares, memory). `directive`: DIR goes into `#SBATCH` lines
/// (Slurm). Prints nothing and creates nothing.
fn plan(c: &Common, binary: String, max_shards: u64, directive: bool) -> anyhow::Result<Plan> {
    let shards = int_flag("--shards", c.shards, 2, max_shards as i64).map_err(|e| {
        if c.shards < 2 {
            anyhow!(
                "--shards {}: at least 2 (one shard is a plain `tstat render`)",
                c.shards
            )
        } else {
            e
        }
    })? as u64;
    let cpus = int_flag("--cpus", c.cpus, 1, super::util::MAX_THREADS)? as u32;
    let mem = c
        .mem
        .as_deref()
        .map(|m| size_flag_in("--mem", m, MIN_RENDER_MEMORY, MAX_TASK_MEMORY))
        .transpose()?;
    let merge_mem = size_flag_in("--merge-mem", &c.merge_mem, (1, "1"), MAX_TASK_MEMORY)?;
    let r = render_args(c, shards)?;
    // Everything `tstat render` checks before loading, so no task fails on it.
    let transform = r.scene_args.transform(&r.transform)?;
    super::util::positive("--unit-m", r.unit_m)?;
    super::util::seed(r.seed)?;
    if let Some(s) = &r.max_memory {
        size_flag("--max-memory", s)?;
    }
    if !r.adaptive {
        r.adaptive_args.refuse_when_off("without --adaptive")?;
    }
    r.adaptive_args.goal(true)?;
    // The paths: absolute (the tasks run elsewhere) and fit for the recipes.
    let absolute = |p: &Path, what: &str| {
        std::path::absolute(p)
            .map(|a| normalize(&a))
            .with_context(|| format!("{what} {}", p.display()))
    };
    let scene_path = absolute(&r.scene, "the scene")?;
    let dir = absolute(&c.out, "--out")?;
    check_path(&scene_path, "the scene", false)?;
    check_path(&dir, "--out", directive)?;
    // Search folders (-a) as absolute paths.
    let mut render_options = Vec::with_capacity(c.render_options.len());
    let mut search_folders = Vec::new();
    let mut it = c.render_options.iter();
    while let Some(o) = it.next() {
        check_text(o, "the render option", false)?;
        let folder = if o == "-a" {
            render_options.push(o.clone());
            it.next().cloned()
        } else if let Some(v) = o.strip_prefix("-a") {
            render_options.push("-a".into());
            Some(v.strip_prefix('=').unwrap_or(v).to_string())
        } else {
            render_options.push(o.clone());
            None
        };
        if let Some(f) = folder {
            let a = absolute(Path::new(&f), "-a")?;
            check_path(&a, "-a", false)?;
            search_folders.push(a.clone());
            render_options.push(a.display().to_string());
        }
    }
    let overrides = r.scene_args.overrides(r.spp)?;
    let scene = Scene::load(&r.scene, &overrides)?;
    let shard = Shard {
        index: 0,
        count: shards,
    };
    // The same split and checks as each task's `tstat render --shard`.
    let (spp, shard_reps) =
        crate::job::render::shard_share(&shard, scene.spp, r.scene_args.replicates)?;
    RenderSettings::check_replicates(spp, shard_reps)?;
    let film = &scene.film;
    let memory = StreamingMemory::new(film, &transform, cpus as usize)
        .with_replicates(shard_reps >= 2, film)
        .with_sampler(
            r.scene_args.pixel_sampling,
            spp,
            shard_reps,
            scene.integrator.volumetric,
        );
    let mib = |b: u64| b.div_ceil(1 << 20);
    let render_mib = match mem {
        Some(m) => mib(m),
        // The estimate covers the buffers; the scene (BVH, textures) and the
        // allocator come on top: twice, and at least 1 GiB.
        None => mib(memory.bytes().saturating_mul(2)).max(1024),
    };
    let merge_mib = mib(merge_mem);
    // The merge holds its bands (its --max-memory) plus the per-pixel images: the
    // output's f64 sums of steady, albedo, normal, depth, emitter, medium (96 bytes a
    // pixel) and one input's arrays (about 64): 160 bytes a pixel, and 64 MiB of slack.
    let images_mib = mib(film.pixels() as u64 * 160) + 64;
    let band_mib = merge_mib.saturating_sub(images_mib);
    anyhow::ensure!(
        band_mib >= 16,
        "--merge-mem {}: the merge of a {}x{} film needs about {images_mib}Mi for its per-pixel images plus at least 16Mi for its bands",
        c.merge_mem,
        film.width,
        film.height
    );
    let shard_bytes = bundle_bytes_with(film, &transform, !scene.media.is_empty(), shard_reps >= 2);
    let summary = format!(
        "{}: {}x{} px, {} bins; {} shards of {} spp; each task {} CPUs, {} MiB; disk {} per shard, {} in all with the merged bundle",
        quote_path(&r.scene),
        film.width,
        film.height,
        film.time.bins,
        shards,
        spp,
        cpus,
        render_mib,
        human_bytes(shard_bytes),
        human_bytes(shard_bytes.saturating_mul(shards + 1))
    );
    let mut inputs = vec![arg("the scene", &r.scene)];
    inputs.extend(scene.mesh_files.iter().map(|p| arg("the mesh", p)));
    Ok(Plan {
        job: Job {
            binary,
            scene: scene_path,
            dir,
            shards,
            render_options,
            denoise: c.denoise,
            cpus,
            render_mib,
            merge_mib,
            band_mib,
        },
        summary,
        inputs,
        search_folders,
    })
}

/// Checks the output folder before anything is created: DIR, `DIR/shards` and
/// `DIR/logs` are folders or absent; the recipes (`files`) are absent, or with `force`
/// files; no output is, holds or lies inside an input (the scene, its meshes, the
/// binary); and nothing of an earlier run is there that the tasks would refuse to
/// replace (shards, the merged bundle, the denoised volume), with or without `force`.
fn check_out(job: &Job, files: &[&str], inputs: &[Arg], force: bool) -> anyhow::Result<()> {
    let d = &job.dir;
    let mut outputs: Vec<Arg> = files.iter().map(|f| arg("--out", d.join(f))).collect();
    outputs.push(arg("--out", d.join("shards")));
    outputs.push(arg("--out", d.join("logs")));
    outputs.push(arg("--out", job.merged()));
    outputs.push(arg("--out", job.denoised()));
    check_collisions(inputs, &outputs)?;
    // DIR's nearest existing ancestor (or DIR itself), shards/ and logs/: folders.
    let nearest = d.ancestors().find(|a| a.exists()).unwrap_or(d);
    for p in [nearest.to_path_buf(), d.join("shards"), d.join("logs")] {
        anyhow::ensure!(
            !p.exists() || p.is_dir(),
            "--out {}: {} exists and is not a folder",
            quote_path(d),
            quote_path(&p)
        );
    }
    for f in files {
        let p = d.join(f);
        if let Ok(m) = std::fs::metadata(&p) {
            anyhow::ensure!(
                force,
                "{}: already exists (use --force to replace it)",
                quote_path(&p)
            );
            anyhow::ensure!(
                !m.is_dir(),
                "{}: is a folder; a recipe is written here, so it is not replaced even with --force",
                quote_path(&p)
            );
        }
    }
    let mut earlier = vec![job.merged()];
    if job.denoise {
        earlier.push(job.denoised());
    }
    if let Ok(it) = std::fs::read_dir(d.join("shards")) {
        let mut shards: Vec<PathBuf> = it
            .flatten()
            .filter(|e| {
                let n = e.file_name();
                let n = n.to_string_lossy();
                n.starts_with("shard-") && n.ends_with(".tstats")
            })
            .map(|e| e.path())
            .collect();
        shards.sort();
        earlier.extend(shards.into_iter().take(1));
    }
    for p in earlier {
        anyhow::ensure!(
            std::fs::symlink_metadata(&p).is_err(),
            "{}: left by an earlier run, and the tasks do not replace it; move it away or choose another --out",
            quote_path(&p)
        );
    }
    Ok(())
}

/// What one run has created: removed again when dropped before [`Staged::commit`]
/// (a failure), so that a failed `tstat cluster` leaves nothing behind. Folders are
/// removed only when empty, so nothing this run did not create is ever removed.
#[derive(Default)]
struct Staged {
    /// Folders this run created, outermost first.
    dirs: Vec<PathBuf>,
    /// Temporary files not yet renamed into place.
    temps: Vec<PathBuf>,
    /// Recipes put in place that did not exist before.
    placed: Vec<PathBuf>,
    committed: bool,
}

impl Staged {
    /// Creates `dir` (and its missing parents), recording what it created.
    fn create_dir(&mut self, dir: &Path) -> anyhow::Result<()> {
        let missing: Vec<&Path> = dir.ancestors().take_while(|a| !a.is_dir()).collect();
        for d in missing.into_iter().rev() {
            std::fs::create_dir(d).with_context(|| format!("creating {}", quote_path(d)))?;
            self.dirs.push(d.to_path_buf());
        }
        Ok(())
    }

    /// Writes `text` under a temporary name next to `dest`; returns that name.
    fn write_temp(&mut self, dest: &Path, text: &str) -> anyhow::Result<PathBuf> {
        let name = dest.file_name().unwrap_or_default().to_string_lossy();
        let tmp = dest.with_file_name(format!(".{name}.partial-{}", std::process::id()));
        self.temps.push(tmp.clone());
        std::fs::write(&tmp, text).with_context(|| format!("writing {}", quote_path(dest)))?;
        Ok(tmp)
    }

    /// Moves `tmp` to `dest`: with `force` replacing a file there, else never (a hard
    /// link fails on an existing name, so nothing that appeared since the checks is
    /// replaced; where links are not supported, a check and a rename).
    fn place(&mut self, tmp: &Path, dest: &Path, force: bool) -> anyhow::Result<()> {
        let existed = std::fs::symlink_metadata(dest).is_ok();
        let r = if force {
            std::fs::rename(tmp, dest)
        } else {
            match std::fs::hard_link(tmp, dest) {
                Ok(()) => std::fs::remove_file(tmp),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(e),
                Err(_) if existed => Err(std::io::ErrorKind::AlreadyExists.into()),
                Err(_) => std::fs::rename(tmp, dest),
            }
        };
        match r {
            Ok(()) => {
                self.temps.retain(|t| t != tmp);
                if !existed {
                    self.placed.push(dest.to_path_buf());
                }
                Ok(())
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                bail!(
                    "{}: already exists (use --force to replace it)",
                    quote_path(dest)
                )
            }
            Err(e) => bail!("writing {}: {e}", quote_path(dest)),
        }
    }

    /// Keeps everything.
    fn commit(mut self) {
        self.committed = true;
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if self.committed {
            return;
        }
        for p in self.temps.iter().chain(&self.placed) {
            let _ = std::fs::remove_file(p);
        }
        for d in self.dirs.iter().rev() {
            let _ = std::fs::remove_dir(d);
        }
    }
}

/// Creates DIR, DIR/shards and DIR/logs, and writes `files` (name, text) into DIR
/// through temporary names (checked first by [`check_out`]); on any failure, removes
/// what it created.
fn write_recipes(job: &Job, files: &[(&str, String)], force: bool) -> anyhow::Result<()> {
    let mut st = Staged::default();
    for d in [
        job.dir.clone(),
        job.dir.join("shards"),
        job.dir.join("logs"),
    ] {
        st.create_dir(&d)?;
    }
    let mut temps = Vec::with_capacity(files.len());
    for (name, text) in files {
        let dest = job.dir.join(name);
        temps.push((st.write_temp(&dest, text)?, dest));
    }
    for (tmp, dest) in &temps {
        st.place(tmp, dest, force)?;
    }
    st.commit();
    Ok(())
}

pub fn run(a: ClusterArgs) -> anyhow::Result<()> {
    match a.scheduler {
        Scheduler::Slurm(s) => {
            slurm::check_time(&s.time)?;
            if let Some(p) = &s.partition {
                slurm::check_partition(p)?;
            }
            let exe = std::env::current_exe()
                .and_then(|p| p.canonicalize())
                .context("finding the tstat binary")?;
            check_path(&exe, "the tstat binary", false)?;
            let Plan {
                job,
                summary,
                mut inputs,
                ..
            } = plan(&s.common, exe.display().to_string(), MAX_SLURM_SHARDS, true)?;
            inputs.push(arg("the tstat binary", &exe));
            let files = ["render.sbatch", "merge.sbatch"];
            check_out(&job, &files, &inputs, s.common.force)?;
            let p = s.partition.as_deref();
            write_recipes(
                &job,
                &[
                    (files[0], slurm::render_script(&job, &s.time, p)),
                    (files[1], slurm::merge_script(&job, &s.time, p)),
                ],
                s.common.force,
            )?;
            eprintln!("{summary}");
            say!(
                "wrote {} and {}; submit:\n  {}",
                quote_path(&job.dir.join(files[0])),
                quote_path(&job.dir.join(files[1])),
                slurm::submit_command(&job)
            );
        }
        Scheduler::K8s(k) => {
            anyhow::ensure!(
                k.mount.starts_with('/'),
                "--mount {}: an absolute path inside the pods",
                k.mount.escape_debug()
            );
            check_text(&k.mount, "--mount", false)?;
            k8s::check_word(&k.image, "--image")?;
            k8s::check_word(&k.binary, "--binary")?;
            k8s::check_claim(&k.claim)?;
            if let Some(n) = &k.name {
                check_text(n, "--name", false)?;
            }
            let parallelism =
                super::util::opt_int::<u64>("--parallelism", k.parallelism, 1, i64::MAX)?;
            let Plan {
                job,
                summary,
                inputs,
                search_folders,
            } = plan(&k.common, k.binary.clone(), k8s::MAX_SHARDS, false)?;
            let mount = normalize(Path::new(&k.mount)).display().to_string();
            k8s::check_under(&job.scene, &mount, "the scene")?;
            k8s::check_under(&job.dir, &mount, "--out")?;
            for f in &search_folders {
                k8s::check_under(f, &mount, "the search folder (-a)")?;
            }
            let stem = job
                .scene
                .file_stem()
                .map_or("tstat".into(), |s| s.to_string_lossy().into_owned());
            let c = k8s::Cluster {
                name: k8s::job_name(k.name.as_deref().unwrap_or(&format!("tstat-{stem}"))),
                image: k.image.clone(),
                claim: k.claim.clone(),
                mount,
                parallelism: parallelism.unwrap_or(job.shards),
            };
            let files = ["render-job.json", "merge-job.json"];
            check_out(&job, &files, &inputs, k.common.force)?;
            let pretty = |v: serde_json::Value| serde_json::to_string_pretty(&v).map(|s| s + "\n");
            write_recipes(
                &job,
                &[
                    (files[0], pretty(k8s::render_job(&c, &job))?),
                    (files[1], pretty(k8s::merge_job(&c, &job))?),
                ],
                k.common.force,
            )?;
            eprintln!("{summary}");
            say!(
                "wrote {} and {}; run:\n  {}",
                quote_path(&job.dir.join(files[0])),
                quote_path(&job.dir.join(files[1])),
                k8s::run_commands(&c, &job).join("\n  ")
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    fn job(dir: &Path) -> Job {
        Job {
            binary: "tstat".into(),
            scene: dir.join("s.xml"),
            dir: dir.to_path_buf(),
            shards: 2,
            render_options: Vec::new(),
            denoise: false,
            cpus: 1,
            render_mib: 1024,
            merge_mib: 1024,
            band_mib: 512,
        }
    }

    /// Every path under `root`, relative, with file contents.
    fn tree(root: &Path) -> BTreeSet<(PathBuf, Vec<u8>)> {
        let mut out = BTreeSet::new();
        let mut stack = vec![root.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap().flatten() {
                let p = e.path();
                let rel = p.strip_prefix(root).unwrap().to_path_buf();
                if p.is_dir() {
                    stack.push(p);
                    out.insert((rel, b"dir".to_vec()));
                } else {
                    out.insert((rel, std::fs::read(&p).unwrap()));
                }
            }
        }
        out
    }

    fn files() -> Vec<(&'static str, String)> {
        vec![
            ("render.sbatch", "r\n".into()),
            ("merge.sbatch", "m\n".into()),
        ]
    }

    #[test]
    fn recipes_are_written_and_kept() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path().join("a/b/run");
        write_recipes(&job(&d), &files(), false).unwrap();
        let names: Vec<PathBuf> = tree(t.path()).into_iter().map(|(p, _)| p).collect();
        let want = [
            "a",
            "a/b",
            "a/b/run",
            "a/b/run/logs",
            "a/b/run/merge.sbatch",
            "a/b/run/render.sbatch",
            "a/b/run/shards",
        ];
        assert_eq!(names, want.map(PathBuf::from));
        assert_eq!(std::fs::read(d.join("merge.sbatch")).unwrap(), b"m\n");
    }

    /// A failure after some recipes are in place: everything this run created goes
    /// (the placed recipe, the temporary file, the folders), what was there stays.
    #[test]
    fn a_failed_write_removes_what_it_created() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path().join("run");
        std::fs::create_dir_all(d.join("merge.sbatch")).unwrap();
        std::fs::write(d.join("merge.sbatch/keep"), "precious").unwrap();
        let before = tree(t.path());
        // With --force a file is renamed over merge.sbatch, a non-empty folder: fails
        // after render.sbatch is in place.
        let e = write_recipes(&job(&d), &files(), true).unwrap_err();
        assert!(e.to_string().starts_with("writing "), "{e}");
        assert_eq!(tree(t.path()), before);
        // Missing parents created by the run go too; the temporary file is
        // written into a folder that does not exist.
        let deep = t.path().join("x/y/z");
        let e = write_recipes(
            &job(&deep),
            &[("render.sbatch", "r".into()), ("no/such", "m".into())],
            false,
        )
        .unwrap_err();
        assert!(e.to_string().contains("no/such"), "{e}");
        assert_eq!(tree(t.path()), before);
    }

    /// Without --force an existing recipe is never replaced, even one that appears
    /// after the checks (the hard link refuses an existing name).
    #[test]
    fn existing_recipes_are_not_replaced_without_force() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path().join("run");
        std::fs::create_dir(&d).unwrap();
        std::fs::write(d.join("merge.sbatch"), "mine").unwrap();
        let before = tree(t.path());
        let e = write_recipes(&job(&d), &files(), false).unwrap_err();
        assert!(
            e.to_string()
                .ends_with("merge.sbatch: already exists (use --force to replace it)"),
            "{e}"
        );
        assert_eq!(tree(t.path()), before);
        let e = check_out(&job(&d), &["render.sbatch", "merge.sbatch"], &[], false).unwrap_err();
        assert!(e.to_string().contains("already exists"), "{e}");
        write_recipes(&job(&d), &files(), true).unwrap();
        assert_eq!(std::fs::read(d.join("merge.sbatch")).unwrap(), b"m\n");
    }
}
