//! Kubernetes: `render-job.json`, an indexed Job (`completionMode: Indexed`, so each pod
//! has `JOB_COMPLETION_INDEX`) of N completions, and `merge-job.json`, a Job of one pod
//! that merges the shards (and may denoise). Kubernetes has no job dependencies: apply
//! the first, `kubectl wait --for=condition=complete job/NAME-render`, then apply the
//! second. JSON is YAML, and `kubectl apply -f` takes either.
//!
//! The pods mount one persistent volume claim at `mount`; the scene and the output
//! folder must lie under it (the same absolute paths inside the pods as where
//! `tstat cluster k8s` ran, e.g. a shared file system mounted at the same place), and
//! the image must hold the tstat binary (`binary`, default `tstat` on its PATH).

use super::{command_line, merge_commands, unprintable, ClusterError, Job};
use serde_json::{json, Value};
use std::path::Path;

/// What the Kubernetes recipe needs beyond the job.
#[derive(Clone, Debug)]
pub struct Cluster {
    /// Job name prefix (a DNS-1123 label of at most 50 characters).
    pub name: String,
    pub image: String,
    pub claim: String,
    pub mount: String,
    /// Pods running at once.
    pub parallelism: u64,
}

/// A DNS-1123 label from `s` (lowercase letters, digits and '-', at most 50
/// characters so that `-render` / `-merge` still fit in 63).
pub fn job_name(s: &str) -> String {
    let mut n: String = s
        .to_ascii_lowercase()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    n.truncate(50);
    let n = n.trim_matches('-').to_string();
    if n.is_empty() {
        "tstat".into()
    } else {
        n
    }
}

/// Checks that `path` lies under the mount point `mount`.
pub fn check_under(path: &Path, mount: &str, what: &str) -> Result<(), ClusterError> {
    if path.starts_with(mount) {
        Ok(())
    } else {
        Err(ClusterError::NotUnderMount {
            what: what.to_string(),
            path: path.to_path_buf(),
            mount: mount.to_string(),
        })
    }
}

/// The most shards of a Kubernetes recipe: an indexed Job takes at most 100,000
/// completions.
pub const MAX_SHARDS: u64 = 100_000;

/// `--claim`: a persistent volume claim's name, a DNS-1123 subdomain (lowercase
/// letters, digits, `-` and `.`, starting and ending with a letter or digit, at most
/// 253 characters).
pub fn check_claim(s: &str) -> Result<(), ClusterError> {
    let ends = |c: Option<char>| c.is_some_and(|c| c.is_ascii_lowercase() || c.is_ascii_digit());
    let ok = s.len() <= 253
        && ends(s.chars().next())
        && ends(s.chars().next_back())
        && s.chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '.');
    if ok {
        Ok(())
    } else {
        Err(ClusterError::Value {
            what: "--claim",
            value: s.to_string(),
            reason: "not a Kubernetes name (lowercase letters, digits, '-' and '.', starting and ending with a letter or digit)",
        })
    }
}

/// `--image` and `--binary`: not empty, no whitespace, control characters or line
/// breaks (an image reference has none; a binary name with them is a mistake).
pub fn check_word(s: &str, what: &'static str) -> Result<(), ClusterError> {
    if s.is_empty() || s.chars().any(|c| c.is_whitespace() || unprintable(c)) {
        Err(ClusterError::Value {
            what,
            value: s.to_string(),
            reason: "empty, or holds whitespace or control characters",
        })
    } else {
        Ok(())
    }
}

/// The commands `tstat cluster k8s` prints to run the Jobs: apply the render Job, wait
/// for it, apply the merge Job; every word quoted ([`super::quote`]).
pub fn run_commands(c: &Cluster, job: &Job) -> Vec<String> {
    let apply = |name: &str| {
        command_line(&[
            "kubectl",
            "apply",
            "-f",
            &job.dir.join(name).to_string_lossy(),
        ])
    };
    vec![
        apply("render-job.json"),
        command_line(&[
            "kubectl",
            "wait",
            "--for=condition=complete",
            "--timeout=24h",
            &format!("job/{}-render", c.name),
        ]),
        apply("merge-job.json"),
    ]
}

fn pod(c: &Cluster, job: &Job, container: &str, command: Vec<String>, mib: u64) -> Value {
    json!({
        "restartPolicy": "Never",
        "containers": [{
            "name": container,
            "image": c.image,
            "command": command,
            "resources": {
                "requests": {"cpu": job.cpus.to_string(), "memory": format!("{mib}Mi")},
                "limits": {"memory": format!("{mib}Mi")}
            },
            "volumeMounts": [{"name": "data", "mountPath": c.mount}]
        }],
        "volumes": [{"name": "data", "persistentVolumeClaim": {"claimName": c.claim}}]
    })
}

/// `render-job.json`.
pub fn render_job(c: &Cluster, job: &Job) -> Value {
    json!({
        "apiVersion": "batch/v1",
        "kind": "Job",
        "metadata": {"name": format!("{}-render", c.name), "labels": {"app": "tstat"}},
        "spec": {
            "completionMode": "Indexed",
            "completions": job.shards,
            "parallelism": c.parallelism.min(job.shards),
            "backoffLimit": job.shards.saturating_mul(2),
            "template": {"spec": pod(c, job, "render", job.render_args(&job.cpus.to_string()), job.render_mib)}
        }
    })
}

/// `merge-job.json`: one pod; the shell expands the shards' glob.
pub fn merge_job(c: &Cluster, job: &Job) -> Value {
    let script = format!(
        "set -eu; {}",
        merge_commands(job, &job.cpus.to_string()).join(" && ")
    );
    json!({
        "apiVersion": "batch/v1",
        "kind": "Job",
        "metadata": {"name": format!("{}-merge", c.name), "labels": {"app": "tstat"}},
        "spec": {
            "completions": 1,
            "backoffLimit": 1,
            "template": {"spec": pod(c, job, "merge", vec!["sh".into(), "-c".into(), script], job.merge_mib)}
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn indexed_job_runs_every_shard_with_the_volume() {
        let job = Job {
            binary: "tstat".into(),
            scene: PathBuf::from("/data/scenes/cbox.xml"),
            dir: PathBuf::from("/data/runs/a"),
            shards: 8,
            render_options: vec!["--spp".into(), "64".into()],
            denoise: true,
            cpus: 2,
            render_mib: 1500,
            merge_mib: 1024,
            band_mib: 800,
        };
        let c = Cluster {
            name: job_name("My Scene_v2.xml"),
            image: "registry/tstat:1".into(),
            claim: "shared".into(),
            mount: "/data".into(),
            parallelism: 4,
        };
        assert_eq!(c.name, "my-scene-v2-xml");
        let r = render_job(&c, &job);
        assert_eq!(r["spec"]["completionMode"], "Indexed");
        assert_eq!(r["spec"]["completions"], 8);
        assert_eq!(r["spec"]["parallelism"], 4);
        let cont = &r["spec"]["template"]["spec"]["containers"][0];
        let cmd: Vec<&str> = cont["command"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(
            cmd,
            [
                "tstat",
                "render",
                "/data/scenes/cbox.xml",
                "--shard",
                "auto/8",
                "--out",
                "/data/runs/a/shards/shard-{shard}.tstats",
                "--threads",
                "2",
                "--spp",
                "64"
            ]
        );
        assert_eq!(cont["resources"]["limits"]["memory"], "1500Mi");
        assert_eq!(cont["volumeMounts"][0]["mountPath"], "/data");
        assert_eq!(
            r["spec"]["template"]["spec"]["volumes"][0]["persistentVolumeClaim"]["claimName"],
            "shared"
        );
        let m = merge_job(&c, &job);
        let script = m["spec"]["template"]["spec"]["containers"][0]["command"][2]
            .as_str()
            .unwrap();
        assert!(
            script.contains(
                "tstat merge /data/runs/a/shards/shard-*.tstats --out /data/runs/a/merged.tstats"
            ),
            "{script}"
        );
        assert!(
            script.contains(
                "&& tstat denoise /data/runs/a/merged.tstats --out /data/runs/a/denoised.npy"
            ),
            "{script}"
        );
        assert!(check_under(&job.scene, "/data", "the scene").is_ok());
        assert_eq!(
            check_under(Path::new("/home/x.xml"), "/data", "the scene"),
            Err(ClusterError::NotUnderMount {
                what: "the scene".into(),
                path: "/home/x.xml".into(),
                mount: "/data".into(),
            })
        );
        assert_eq!(job_name("---"), "tstat");
    }
}
