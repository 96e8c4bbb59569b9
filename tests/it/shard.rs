//! Shards of one render job (`render --shard`) and their merge: the shards split the
//! job's spp and seeds, the scheduler's index variables work, merge streams in bounded
//! memory to the same bits whatever the order or band size, and refuses a job with
//! shards missing, repeated or mixed with another job's.

use std::path::Path;
use std::process::{Command, Output};

fn tstat(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tstat"));
    c.args(args)
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX");
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().unwrap()
}

fn ok(r: &Output) -> String {
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    String::from_utf8_lossy(&r.stderr).into_owned()
}

fn fails(r: &Output, needle: &str) {
    let e = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success(), "expected a failure naming {needle:?}");
    assert!(e.contains(needle), "expected {needle:?} in: {e}");
    assert!(!e.contains("panicked"), "{e}");
}

fn cbox() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/cbox.xml")
        .display()
        .to_string()
}

const FILM: &[&str] = &["--width", "12", "--bins", "24"];

fn render(out: &str, extra: &[&str], env: &[(&str, &str)]) -> Output {
    let sc = cbox();
    let mut args = vec!["render", sc.as_str(), "--out", out];
    args.extend_from_slice(FILM);
    // spp 8 and seed 5 unless `extra` says otherwise.
    for (flag, default) in [("--spp", "8"), ("--seed", "5")] {
        if !extra.contains(&flag) {
            args.extend_from_slice(&[flag, default]);
        }
    }
    args.extend_from_slice(extra);
    tstat(&args, env)
}

fn manifest(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap()).unwrap()
}

/// Every array file of a bundle, bytes (the manifest aside: it holds times).
fn arrays(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "npy"))
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn shards_render_their_share_and_merge_to_the_same_bits_in_any_order() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    for i in 0..4 {
        ok(&render(
            &p(&format!("s{i}.tstats")),
            &["--shard", &format!("{i}/4")],
            &[],
        ));
    }
    let m: Vec<_> = (0..4)
        .map(|i| manifest(&dir.path().join(format!("s{i}.tstats"))))
        .collect();
    let job = m[0]["shard"]["job"].as_str().unwrap().to_string();
    let mut seeds = std::collections::BTreeSet::new();
    for (i, mi) in m.iter().enumerate() {
        assert_eq!(mi["spp"], 2, "each shard renders 8 / 4 spp");
        assert_eq!(mi["shard"]["job"], job.as_str(), "one job");
        assert_eq!(mi["shard"]["count"], 4);
        assert_eq!(mi["shard"]["indices"], serde_json::json!([i]));
        seeds.insert(mi["seed"].as_u64().unwrap());
    }
    assert_eq!(seeds.len(), 4, "every shard has its own seed");
    // Rendering shard 2 again gives the same bits (and the same job).
    ok(&render(&p("again.tstats"), &["--shard", "2/4"], &[]));
    assert_eq!(
        arrays(&dir.path().join("again.tstats")),
        arrays(&dir.path().join("s2.tstats"))
    );
    assert_eq!(
        manifest(&dir.path().join("again.tstats"))["shard"]["job"],
        job.as_str()
    );

    // Merge in two orders, and with one-row bands: the same bits.
    let merge = |order: [usize; 4], out: &str, extra: &[&str]| {
        let names: Vec<String> = order.iter().map(|i| p(&format!("s{i}.tstats"))).collect();
        let mut args: Vec<&str> = vec!["merge"];
        args.extend(names.iter().map(String::as_str));
        let o = p(out);
        args.extend_from_slice(&["--out", &o]);
        args.extend_from_slice(extra);
        tstat(&args, &[])
    };
    ok(&merge([0, 1, 2, 3], "m1.tstats", &[]));
    ok(&merge([3, 1, 0, 2], "m2.tstats", &[]));
    ok(&merge([2, 0, 3, 1], "m3.tstats", &["--max-memory", "1"]));
    let r = merge([0, 1, 2, 3], "bad.tstats", &["--max-memory", "lots"]);
    fails(&r, "--max-memory lots: not a size");
    let a = arrays(&dir.path().join("m1.tstats"));
    assert_eq!(a, arrays(&dir.path().join("m2.tstats")));
    assert_eq!(a, arrays(&dir.path().join("m3.tstats")));
    let mm = manifest(&dir.path().join("m1.tstats"));
    assert_eq!(mm["spp"], 8);
    assert_eq!(mm["shard"]["indices"], serde_json::json!([0, 1, 2, 3]));
    // The merged sums are the shards' sums (in the canonical order, exactly).
    let x1 = |d: &str| -> ndarray::ArrayD<f64> {
        ndarray_npy::read_npy(dir.path().join(d).join("x1.npy")).unwrap()
    };
    let mut order: Vec<usize> = (0..4).collect();
    order.sort_by_key(|&i| m[i]["seed"].as_u64().unwrap());
    let mut sum = x1(&format!("s{}.tstats", order[0]));
    for &i in &order[1..] {
        sum = sum + x1(&format!("s{i}.tstats"));
    }
    assert_eq!(x1("m1.tstats"), sum);
    let info = tstat(&["info", &p("m1.tstats")], &[]);
    assert!(
        String::from_utf8_lossy(&info.stdout)
            .contains(&format!("job         {job} (all 4 shards)")),
        "{}",
        String::from_utf8_lossy(&info.stdout)
    );
    // The merged job is a bundle like any other: it denoises.
    ok(&tstat(
        &["denoise", &p("m1.tstats"), "--out", &p("m1.npy")],
        &[],
    ));

    // Missing, repeated, and another job's shards.
    let three = |a: &str, b: &str, c: &str, extra: &[&str]| {
        let (a, b, c, o) = (p(a), p(b), p(c), p("bad.tstats"));
        let mut args = vec![
            "merge",
            a.as_str(),
            b.as_str(),
            c.as_str(),
            "--out",
            o.as_str(),
        ];
        args.extend_from_slice(extra);
        tstat(&args, &[])
    };
    fails(
        &three("s0.tstats", "s1.tstats", "s3.tstats", &[]),
        "1 of its 4 shards are missing: 2 (render them, or merge with --partial)",
    );
    assert!(!dir.path().join("bad.tstats").exists());
    ok(&three(
        "s0.tstats",
        "s1.tstats",
        "s3.tstats",
        &["--partial"],
    ));
    assert_eq!(
        manifest(&dir.path().join("bad.tstats"))["shard"]["indices"],
        serde_json::json!([0, 1, 3])
    );
    fails(
        &three(
            "s0.tstats",
            "s2.tstats",
            "again.tstats",
            &["--partial", "--force"],
        ),
        "shard 2 of 4 is given twice",
    );
    // A partial merge and the missing shard complete the job.
    let (b, s2, full) = (p("bad.tstats"), p("s2.tstats"), p("full.tstats"));
    ok(&tstat(&["merge", &b, &s2, "--out", &full], &[]));
    assert_eq!(
        manifest(&dir.path().join("full.tstats"))["shard"]["indices"],
        serde_json::json!([0, 1, 2, 3])
    );
    // Shard 1 of a job with another seed is another job.
    ok(&render(
        &p("other1.tstats"),
        &["--shard", "1/4", "--seed", "6"],
        &[],
    ));
    let other = manifest(&dir.path().join("other1.tstats"));
    assert_ne!(other["shard"]["job"], job.as_str());
    fails(
        &three("s0.tstats", "other1.tstats", "s2.tstats", &["--force"]),
        "shards are missing",
    );
}

#[test]
fn the_scheduler_gives_the_index() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let pattern = p("shard-{shard}.tstats");
    ok(&render(
        &pattern,
        &["--shard", "auto/4"],
        &[("SLURM_ARRAY_TASK_ID", "2")],
    ));
    ok(&render(
        &pattern,
        &["--shard", "auto/4"],
        &[("JOB_COMPLETION_INDEX", "3")],
    ));
    ok(&render(&p("explicit.tstats"), &["--shard", "2/4"], &[]));
    assert_eq!(
        arrays(&dir.path().join("shard-2.tstats")),
        arrays(&dir.path().join("explicit.tstats"))
    );
    assert_eq!(
        manifest(&dir.path().join("shard-3.tstats"))["shard"]["indices"],
        serde_json::json!([3])
    );
    // Two digits for 16 shards.
    ok(&render(
        &pattern,
        &["--shard", "auto/16", "--spp", "32"],
        &[("SLURM_ARRAY_TASK_ID", "7"), ("JOB_COMPLETION_INDEX", "1")],
    ));
    assert!(dir.path().join("shard-07.tstats").is_dir());
    fails(
        &render(
            &p("x.tstats"),
            &["--shard", "auto/4"],
            &[("SLURM_ARRAY_TASK_ID", "1")],
        ),
        "put {shard} in the path",
    );
    fails(
        &render(&pattern, &["--shard", "auto/4"], &[]),
        "neither SLURM_ARRAY_TASK_ID nor JOB_COMPLETION_INDEX is set",
    );
    fails(
        &render(
            &pattern,
            &["--shard", "auto/4"],
            &[("SLURM_ARRAY_TASK_ID", "4")],
        ),
        "index 4 (SLURM_ARRAY_TASK_ID) is not below the number of shards 4",
    );
    fails(
        &render(&p("y.tstats"), &["--shard", "4/4"], &[]),
        "is not below",
    );
    fails(
        &render(&p("y.tstats"), &["--shard", "1/3"], &[]),
        "the job's spp 8 is not a multiple of the number of shards 3",
    );
    fails(
        &render(&p("y.tstats"), &["--shard", "1/8"], &[]),
        "leaves 1 per shard",
    );
    fails(
        &render(
            &p("y.tstats"),
            &["--shard", "1/2", "--replicates", "2"],
            &[],
        ),
        "--replicates 2 over 2 shards leaves 1 per shard",
    );
    fails(
        &render(&p("y.tstats"), &["--shard", "two/4"], &[]),
        "expected I/N or auto/N",
    );
    assert!(!dir.path().join("y.tstats").exists());
}

/// With replicates, each shard renders B / N of them and the merge adds them back.
#[test]
fn replicates_split_over_shards_and_add_back() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    for i in 0..2 {
        ok(&render(
            &p(&format!("r{i}.tstats")),
            &["--shard", &format!("{i}/2"), "--replicates", "4"],
            &[],
        ));
        let m = manifest(&dir.path().join(format!("r{i}.tstats")));
        assert_eq!(
            (m["spp"].as_u64(), m["replicates"].as_u64()),
            (Some(4), Some(2))
        );
    }
    ok(&tstat(
        &[
            "merge",
            &p("r0.tstats"),
            &p("r1.tstats"),
            "--out",
            &p("r.tstats"),
        ],
        &[],
    ));
    let m = manifest(&dir.path().join("r.tstats"));
    assert_eq!(
        (m["spp"].as_u64(), m["replicates"].as_u64()),
        (Some(8), Some(4))
    );
}

/// `tstat cluster slurm` writes scripts that work: run here by bash with the variables
/// Slurm would set, they render every shard and merge them into the job's bundle, the
/// same bytes as a local render and merge of the same shards. Bad options are refused
/// before anything is written.
#[test]
fn slurm_recipes_run_as_slurm_would_run_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("job");
    let ds = d.display().to_string();
    let sc = cbox();
    let opts = [
        "--", "--spp", "8", "--width", "12", "--bins", "24", "--seed", "5",
    ];
    let base = [
        "cluster",
        "slurm",
        sc.as_str(),
        "--shards",
        "4",
        "--out",
        ds.as_str(),
        "--cpus",
        "1",
        "--denoise",
    ];
    let cluster = |extra: &[&str], opts: &[&str]| {
        let mut a = base.to_vec();
        a.extend_from_slice(extra);
        a.extend_from_slice(opts);
        tstat(&a, &[])
    };
    fails(
        &cluster(&[], &["--", "--spp", "6"]),
        "the job's spp 6 is not a multiple of the number of shards 4",
    );
    fails(
        &cluster(&[], &["--", "--out", "x"]),
        "--out among the render options",
    );
    fails(
        &cluster(&[], &["--", "--spp", "8", "--wat"]),
        "do not parse as tstat render's",
    );
    fails(
        &cluster(&["--time", "2h"], &opts),
        "expected a Slurm time limit",
    );
    fails(
        &cluster(&[], &["--", "--spp", "8", "--unit-m", "0"]),
        "--unit-m",
    );
    fails(
        &cluster(&[], &["--", "--spp", "8", "--max-memory", "lots"]),
        "--max-memory",
    );
    fails(
        &cluster(&["--merge-mem", "70Mi"], &opts),
        "per-pixel images",
    );
    assert!(!d.exists(), "nothing written on refusal");
    let spaced = dir.path().join("run 1").display().to_string();
    fails(
        &tstat(
            &[
                "cluster",
                "slurm",
                sc.as_str(),
                "--shards",
                "4",
                "--out",
                &spaced,
                "--",
                "--spp",
                "8",
            ],
            &[],
        ),
        "Slurm directive lines take no spaces",
    );
    ok(&cluster(&[], &opts));
    fails(&cluster(&[], &opts), "render.sbatch: already exists");
    // A relative search folder becomes absolute: the tasks run in another folder.
    let repo = env!("CARGO_MANIFEST_DIR");
    let r = Command::new(env!("CARGO_BIN_EXE_tstat"))
        .current_dir(repo)
        .args(base)
        .arg("--force")
        .args(opts)
        .args(["-a", "scenes"])
        .output()
        .unwrap();
    ok(&r);
    let script = std::fs::read_to_string(d.join("render.sbatch")).unwrap();
    assert!(script.contains(&format!(" -a {repo}/scenes")), "{script}");
    ok(&cluster(&["--force"], &opts));
    let script = std::fs::read_to_string(d.join("render.sbatch")).unwrap();
    assert!(
        script.contains("#SBATCH --array=0-3\n") && script.contains("--shard auto/4"),
        "{script}"
    );
    if Command::new("bash").arg("--version").output().is_err() {
        return; // no bash to run the scripts with
    }
    for i in 0..4 {
        let r = Command::new("bash")
            .arg(d.join("render.sbatch"))
            .env("SLURM_ARRAY_TASK_ID", i.to_string())
            .env("SLURM_CPUS_PER_TASK", "1")
            .env("PATH", std::env::var("PATH").unwrap_or_default())
            .output()
            .unwrap();
        ok(&r);
    }
    ok(&Command::new("bash")
        .arg(d.join("merge.sbatch"))
        .output()
        .unwrap());
    assert!(d.join("denoised.npy").is_file());
    let merged = manifest(&d.join("merged.tstats"));
    assert_eq!(merged["shard"]["indices"], serde_json::json!([0, 1, 2, 3]));
    // The same shards rendered and merged by hand.
    let p = |n: &str| dir.path().join(n).display().to_string();
    for i in 0..4 {
        ok(&render(
            &p(&format!("l{i}.tstats")),
            &["--shard", &format!("{i}/4"), "--threads", "2"],
            &[],
        ));
    }
    ok(&tstat(
        &[
            "merge",
            &p("l2.tstats"),
            &p("l0.tstats"),
            &p("l3.tstats"),
            &p("l1.tstats"),
            "--out",
            &p("local.tstats"),
        ],
        &[],
    ));
    assert_eq!(
        arrays(&d.join("merged.tstats")),
        arrays(&dir.path().join("local.tstats"))
    );
}

/// `tstat cluster k8s` writes an indexed Job whose pods see the scene and the output
/// through the claim, and refuses paths outside the mount.
#[test]
fn k8s_recipes_are_indexed_jobs_on_the_shared_volume() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("job");
    let ds = d.display().to_string();
    let root = env!("CARGO_MANIFEST_DIR");
    let sc = cbox();
    let k8s = |mount: &str| {
        tstat(
            &[
                "cluster",
                "k8s",
                &sc,
                "--shards",
                "2",
                "--out",
                &ds,
                "--image",
                "reg/tstat:1",
                "--claim",
                "data",
                "--mount",
                mount,
                "--",
                "--spp",
                "4",
            ],
            &[],
        )
    };
    fails(
        &k8s("/nowhere"),
        "is not under the volume's mount point /nowhere",
    );
    fails(&k8s("relative"), "an absolute path inside the pods");
    // `..` cannot lead out of the mount.
    let mount = dir.path().display().to_string();
    let inside = dir.path().join("cbox.xml");
    std::fs::copy(&sc, &inside).unwrap();
    let sneaky = format!("{mount}/../x");
    let r = tstat(
        &[
            "cluster",
            "k8s",
            inside.to_str().unwrap(),
            "--shards",
            "2",
            "--out",
            &sneaky,
            "--image",
            "i",
            "--claim",
            "c",
            "--mount",
            &mount,
            "--",
            "--spp",
            "4",
        ],
        &[],
    );
    let outside = dir.path().parent().unwrap().join("x");
    fails(
        &r,
        &format!(
            "--out {} is not under the volume's mount point",
            outside.display()
        ),
    );
    // Both the scene and DIR must be under the mount: use their common ancestor.
    let common = Path::new(root)
        .ancestors()
        .find(|a| d.starts_with(a))
        .unwrap()
        .display()
        .to_string();
    ok(&k8s(&common));
    let job: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("render-job.json")).unwrap()).unwrap();
    assert_eq!(job["spec"]["completionMode"], "Indexed");
    assert_eq!(job["spec"]["completions"], 2);
    let cmd = &job["spec"]["template"]["spec"]["containers"][0]["command"];
    assert_eq!(cmd[1], "render");
    assert_eq!(cmd[4], "auto/2");
    let merge: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("merge-job.json")).unwrap()).unwrap();
    assert!(
        merge["spec"]["template"]["spec"]["containers"][0]["command"][2]
            .as_str()
            .unwrap()
            .contains(" merge ")
    );
}
