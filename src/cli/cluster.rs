//! `tstat cluster slurm|k8s SCENE --shards N --out DIR [options] -- [render options]`:
//! writes the recipes of `crate::cluster` after checking, here, everything a task would
//! otherwise find out on the cluster: the render options (parsed as `render`'s), the
//! scene (loaded), the split of spp and replicates over the shards, and the memory a
//! task needs (the render's own estimate at the task's threads).

use super::render::RenderArgs;
use super::util::{human_bytes, parse_bytes};
use crate::bundle::shard::Shard;
use crate::bundle::write::bundle_bytes_with;
use crate::cluster::{check_path, k8s, normalize, slurm, Job};
use crate::render::{RenderSettings, StreamingMemory};
use crate::scene::Scene;
use crate::stats::Transform;
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
    /// Number of shards N (at least 2): each renders spp / N samples per pixel.
    #[arg(long)]
    pub shards: u64,
    /// Output folder (created): the recipes, shards/, logs/, then merged.tstats.
    #[arg(long)]
    pub out: PathBuf,
    /// CPUs of one task (its render threads).
    #[arg(long, default_value_t = 4)]
    pub cpus: u32,
    /// Memory of one render task (e.g. 4Gi; 4G is 4e9 bytes; default: twice the
    /// render's own estimate at --cpus threads, at least 1Gi).
    #[arg(long)]
    pub mem: Option<String>,
    /// Memory of the merge (and denoise) task; the merge's per-pixel images take about
    /// 160 bytes a pixel plus 64Mi, its bands and the denoiser the rest.
    #[arg(long, default_value = "2Gi")]
    pub merge_mem: String,
    /// Also denoise the merged bundle into DIR/denoised.npy.
    #[arg(long)]
    pub denoise: bool,
    /// Replace recipes already in DIR.
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
    /// Time limit of each task (Slurm's format: minutes, HH:MM:SS or D-HH:MM:SS).
    #[arg(long, default_value = "02:00:00")]
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
    /// Pods running at once (default: every shard).
    #[arg(long)]
    pub parallelism: Option<u64>,
    /// Job name prefix (default: from the scene's file name).
    #[arg(long)]
    pub name: Option<String>,
}

/// Parses the render options as `tstat render SCENE --out X --shard 0/N ...` would.
fn render_args(c: &Common) -> anyhow::Result<RenderArgs> {
    for o in &c.render_options {
        let flag = o.split('=').next().unwrap_or(o);
        if ["--out", "--shard", "--threads"].contains(&flag) {
            bail!("{flag} among the render options: the recipe sets it (shards go to DIR/shards, threads are --cpus)");
        }
    }
    let scene = c.scene.display().to_string();
    let shard = format!("0/{}", c.shards);
    let mut argv = vec!["tstat", "render", &scene, "--out", "x", "--shard", &shard];
    argv.extend(c.render_options.iter().map(String::as_str));
    match super::Cli::try_parse_from(argv) {
        Ok(super::Cli {
            command: super::Command::Render(r),
        }) => Ok(r),
        Ok(_) => unreachable!("parsed as render"),
        Err(e) => Err(anyhow!(
            "the render options do not parse as tstat render's: {}",
            e.to_string().lines().next().unwrap_or_default()
        )),
    }
}

/// Checks the job and makes its description (scene loaded, shares, memory); also
/// returns the search folders (`-a`, absolute) the tasks will read.
fn plan(c: &Common, binary: String, search_folders: &mut Vec<PathBuf>) -> anyhow::Result<Job> {
    anyhow::ensure!(
        c.shards >= 2,
        "--shards {}: at least 2 (one shard is a plain `tstat render`)",
        c.shards
    );
    anyhow::ensure!(
        (1..=1024).contains(&c.cpus),
        "--cpus {}: from 1 to 1024",
        c.cpus
    );
    let r = render_args(c)?;
    // Everything `tstat render` checks before loading, so no task fails on it.
    let transform: Transform = r
        .transform
        .parse()
        .map_err(|e| anyhow!("--transform: {e}"))?;
    super::util::positive("--unit-m", r.unit_m)?;
    super::util::seed(r.seed)?;
    if let Some(s) = &r.max_memory {
        parse_bytes(s).map_err(|e| anyhow!("--max-memory: {e}"))?;
    }
    let overrides = r.scene_args.overrides(r.spp)?;
    let scene = Scene::load(&r.scene, &overrides)?;
    let shard = Shard {
        index: 0,
        count: c.shards,
    };
    // The same split and checks as each task's `tstat render --shard`.
    let (spp, shard_reps) = super::render::shard_share(&shard, scene.spp, r.scene_args.replicates)?;
    RenderSettings::check_replicates(spp, shard_reps)?;
    let film = &scene.film;
    let memory = StreamingMemory::new(film, &transform, c.cpus as usize)
        .with_replicates(shard_reps >= 2, film)
        .with_sampler(
            r.scene_args.pixel_sampling,
            spp,
            shard_reps,
            scene.integrator.volumetric,
        );
    let mib = |b: u64| b.div_ceil(1 << 20);
    let render_mib = match &c.mem {
        Some(m) => mib(parse_bytes(m).map_err(|e| anyhow!("--mem: {e}"))?),
        // The estimate covers the buffers; the scene (BVH, textures) and the
        // allocator come on top: twice, and at least 1 GiB.
        None => mib(memory.bytes().saturating_mul(2)).max(1024),
    };
    let merge_mib = mib(parse_bytes(&c.merge_mem).map_err(|e| anyhow!("--merge-mem: {e}"))?);
    anyhow::ensure!(render_mib >= 64, "--mem {render_mib}Mi: at least 64Mi");
    // The merge holds its bands (its --max-memory) plus the per-pixel images: the
    // output's f64 sums of steady, albedo, normal, depth, emitter, medium (96 bytes a
    // pixel) and one input's arrays (about 64): 160 bytes a pixel, and 64 MiB of slack.
    let images_mib = mib(film.pixels() as u64 * 160) + 64;
    let band_mib = merge_mib.saturating_sub(images_mib);
    anyhow::ensure!(
        band_mib >= 16,
        "--merge-mem {merge_mib}Mi: the merge of a {}x{} film needs about {images_mib}Mi for its per-pixel images plus at least 16Mi for its bands",
        film.width,
        film.height
    );
    let shard_bytes = bundle_bytes_with(film, &transform, !scene.media.is_empty(), shard_reps >= 2);
    eprintln!(
        "{}: {}x{} px, {} bins; {} shards of {} spp; each task {} CPUs, {} MiB; disk {} per shard, {} in all with the merged bundle",
        r.scene.display(),
        film.width,
        film.height,
        film.bins,
        c.shards,
        spp,
        c.cpus,
        render_mib,
        human_bytes(shard_bytes),
        human_bytes(shard_bytes.saturating_mul(c.shards + 1))
    );
    let absolute = |p: &Path, what: &str| {
        std::path::absolute(p)
            .map(|a| normalize(&a))
            .with_context(|| format!("{what} {}", p.display()))
    };
    let scene = absolute(&r.scene, "the scene")?;
    let dir = absolute(&c.out, "--out")?;
    check_path(&scene, "the scene", false)?;
    check_path(&dir, "--out", true)?;
    // Search folders (-a) as absolute paths: tasks run elsewhere.
    let mut render_options = Vec::with_capacity(c.render_options.len());
    let mut it = c.render_options.iter();
    while let Some(o) = it.next() {
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
    Ok(Job {
        binary,
        scene,
        dir,
        shards: c.shards,
        render_options,
        denoise: c.denoise,
        cpus: c.cpus,
        render_mib,
        merge_mib,
        band_mib,
    })
}

/// Creates DIR, DIR/shards and DIR/logs, and writes `files` (name, text) into DIR
/// through temporary names; existing recipes are replaced only with `force`.
fn write_recipes(job: &Job, files: &[(&str, String)], force: bool) -> anyhow::Result<()> {
    for (name, _) in files {
        let p = job.dir.join(name);
        anyhow::ensure!(
            force || !p.exists(),
            "{}: already exists (use --force to replace it)",
            p.display()
        );
    }
    for d in [
        job.dir.clone(),
        job.dir.join("shards"),
        job.dir.join("logs"),
    ] {
        std::fs::create_dir_all(&d).with_context(|| format!("creating {}", d.display()))?;
    }
    for (name, text) in files {
        let p = job.dir.join(name);
        let tmp = job
            .dir
            .join(format!(".{name}.partial-{}", std::process::id()));
        std::fs::write(&tmp, text)
            .and_then(|()| std::fs::rename(&tmp, &p))
            .with_context(|| format!("writing {}", p.display()))?;
    }
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
            let job = plan(&s.common, exe.display().to_string(), &mut Vec::new())?;
            let p = s.partition.as_deref();
            write_recipes(
                &job,
                &[
                    ("render.sbatch", slurm::render_script(&job, &s.time, p)),
                    ("merge.sbatch", slurm::merge_script(&job, &s.time, p)),
                ],
                s.common.force,
            )?;
            say!(
                "wrote {0}/render.sbatch and {0}/merge.sbatch; submit:\n  sbatch {0}/render.sbatch\n  sbatch --dependency=afterok:<job id> {0}/merge.sbatch",
                job.dir.display()
            );
        }
        Scheduler::K8s(k) => {
            anyhow::ensure!(
                k.mount.starts_with('/'),
                "--mount {}: an absolute path inside the pods",
                k.mount
            );
            for (v, what) in [
                (&k.image, "--image"),
                (&k.claim, "--claim"),
                (&k.binary, "--binary"),
            ] {
                anyhow::ensure!(!v.trim().is_empty(), "{what}: empty");
            }
            let mut folders = Vec::new();
            let job = plan(&k.common, k.binary.clone(), &mut folders)?;
            let mount = normalize(Path::new(&k.mount)).display().to_string();
            k8s::check_under(&job.scene, &mount, "the scene")?;
            k8s::check_under(&job.dir, &mount, "--out")?;
            for f in &folders {
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
                mount: k.mount.clone(),
                parallelism: k.parallelism.unwrap_or(job.shards).max(1),
            };
            let pretty = |v: serde_json::Value| {
                serde_json::to_string_pretty(&v).expect("json serialises") + "\n"
            };
            write_recipes(
                &job,
                &[
                    ("render-job.json", pretty(k8s::render_job(&c, &job))),
                    ("merge-job.json", pretty(k8s::merge_job(&c, &job))),
                ],
                k.common.force,
            )?;
            say!(
                "wrote {0}/render-job.json and {0}/merge-job.json; run:\n  kubectl apply -f {0}/render-job.json\n  kubectl wait --for=condition=complete --timeout=24h job/{1}-render\n  kubectl apply -f {0}/merge-job.json",
                job.dir.display(),
                c.name
            );
        }
    }
    Ok(())
}
