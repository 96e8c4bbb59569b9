//! Participating media and `transient_prbvolpath` (SPEC 7): closed forms and
//! invariants.
//!
//! - single scattering in an infinite homogeneous medium, confocal point light, against
//!   its arrival-time density, per bin and per channel (chromatic extinction, so the
//!   free-flight sampling's spectral MIS is checked for every channel);
//! - a non-absorbing medium (albedo 1) inside a uniform emitter keeps radiance 1
//!   everywhere (a furnace: scattering loses no energy);
//! - a fog of vanishing extinction renders what the scene without it renders (the
//!   surface integrator), bin by bin;
//! - scenes naming `transient_path` but holding media are refused.

mod common;

use common::{load, run};
use std::f64::consts::PI;
use std::path::Path;
use tstat::scene::{Overrides, Scene};

/// An infinite medium around the camera (the sensor's medium) with a point light at
/// the pinhole; no surfaces. `PHASE` is replaced by the phase function.
const CONFOCAL_MEDIUM: &str = r#"<scene version="3.0.0">
  <integrator type="transient_prbvolpath"><integer name="max_depth" value="2"/></integrator>
  <medium type="homogeneous" id="fog">
    <rgb name="sigma_t" value="0.5, 1.0, 2.0"/>
    <rgb name="albedo" value="0.9, 0.5, 0.3"/>
    PHASE
  </medium>
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <ref name="medium" id="fog"/>
    <sampler type="independent"><integer name="sample_count" value="256"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="32"/><integer name="height" value="32"/>
      <integer name="temporal_bins" value="16"/>
      <float name="start_opl" value="0.5"/>
      <float name="bin_width_opl" value="0.25"/>
    </film>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="0"/><rgb name="intensity" value="1"/></emitter>
</scene>"#;

/// Composite Simpson's rule with `n` (even) intervals.
fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    let mut s = f(a) + f(b);
    for i in 1..n {
        s += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

/// Single scattering, derived for this test.
///
/// A camera ray along d meets no surface; with max_depth = 2 the only contributions
/// are next-event estimates from the first real scattering (the point light cannot be
/// hit, and a second scattering ends the path at depth 2). A scattering at distance s
/// along the ray sees the light at distance s straight back: the radiance reaching the
/// pinhole through it is
///   L = integral_0^inf exp(-sigma_t s) sigma_s p(wi = -d, wo = -d) I exp(-sigma_t s) / s^2 ds,
/// the two exponentials being the transmittances of the camera segment and of the
/// light segment, I / s^2 the irradiance of the point light, p the phase function at
/// Mitsuba's `dot(wo, wi) = 1` (light scattered straight back: 1/(4 pi) for
/// isotropic, (1 - g^2) / (4 pi (1 + g)^3) for hg). The path's OPL is 2 s (index 1),
/// so the density in OPL tau is L(tau) = 2 sigma_s p I exp(-sigma_t tau) / tau^2 and
/// bin [tau_a, tau_b) holds
///   sigma_s p I integral_{tau_a/2}^{tau_b/2} exp(-2 sigma_t s) / s^2 ds,
/// the same for every pixel (the medium is infinite and the phase function depends
/// only on the angle between wi and wo, here 0). Each channel has its own sigma_t.
fn single_scattering_bin(sigma_t: f64, sigma_s: f64, p_back: f64, tau_a: f64, tau_b: f64) -> f64 {
    sigma_s
        * p_back
        * simpson(
            |s| (-2.0 * sigma_t * s).exp() / (s * s),
            tau_a / 2.0,
            tau_b / 2.0,
            2000,
        )
}

#[test]
fn single_scattering_in_an_infinite_medium_matches_its_arrival_time_density() {
    let sigma_t = [0.5, 1.0, 2.0];
    let albedo = [0.9, 0.5, 0.3];
    let hg = |g: f64| (1.0 - g * g) / (4.0 * PI * (1.0 + g).powi(3));
    for (phase, p_back, seed) in [
        (r#"<phase type="isotropic"/>"#, 1.0 / (4.0 * PI), 3u64),
        (
            r#"<phase type="hg"><float name="g" value="-0.6"/></phase>"#,
            hg(-0.6),
            4,
        ),
    ] {
        let scene = load(
            &CONFOCAL_MEDIUM.replace("PHASE", phase),
            &Overrides::default(),
        );
        let out = run(&scene, seed);
        let (t_bins, pixels) = (scene.film.bins, scene.film.pixels());
        // Every pixel estimates the same value: pool them (independent samples).
        let n = (pixels as u64 * scene.spp as u64) as f64;
        let mut worst = 0.0f64;
        for k in 0..t_bins {
            let tau_a = scene.film.start_opl + k as f64 * scene.film.bin_width_opl;
            let tau_b = tau_a + scene.film.bin_width_opl;
            for c in 0..3 {
                let (mut s1, mut s2) = (0.0, 0.0);
                for p in 0..pixels {
                    let v = (p * t_bins + k) * 3 + c;
                    s1 += out.accum.x1[v];
                    s2 += out.accum.x2[v];
                }
                let mean = s1 / n;
                let var = (s2 / n - mean * mean).max(0.0) * n / (n - 1.0);
                let se = (var / n).sqrt();
                let want =
                    single_scattering_bin(sigma_t[c], sigma_t[c] * albedo[c], p_back, tau_a, tau_b);
                let z = (mean - want) / se;
                worst = worst.max(z.abs());
                // 4.5 standard errors: 96 comparisons, a false failure below 1e-3.
                assert!(
                    z.abs() < 4.5,
                    "{phase} bin {k} channel {c}: {mean} vs {want} (z = {z:.2}, se {se:.2e})"
                );
                // The Monte Carlo error is small enough for the test to mean something.
                assert!(se < 0.03 * want, "bin {k} channel {c}: se {se} vs {want}");
            }
        }
        eprintln!("{phase}: largest |z| over 48 bins x channels {worst:.2}");
    }
}

/// A sphere of radius 1 emitting radiance 1 inwards (black otherwise) filled with a
/// non-absorbing medium that also surrounds the camera at its centre.
const FURNACE: &str = r#"<scene version="3.0.0">
  <integrator type="transient_prbvolpath"><integer name="max_depth" value="-1"/></integrator>
  <medium type="homogeneous" id="fog">
    <rgb name="sigma_t" value="SIGMA_T"/>
    <float name="albedo" value="1"/>
    <phase type="hg"><float name="g" value="0.5"/></phase>
  </medium>
  <sensor type="perspective">
    <float name="fov" value="90"/>
    <ref name="medium" id="fog"/>
    <sampler type="independent"><integer name="sample_count" value="SPP"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="16"/><integer name="height" value="16"/>
      <integer name="temporal_bins" value="1"/>
      <float name="bin_width_opl" value="1000"/>
    </film>
  </sensor>
  <shape type="sphere">
    <boolean name="flip_normals" value="true"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
    <emitter type="area"><rgb name="radiance" value="1"/></emitter>
    <ref name="interior" id="fog"/>
  </shape>
</scene>"#;

#[test]
fn a_non_absorbing_medium_in_a_uniform_emitter_loses_no_energy() {
    // The RTE's solution is L = 1 everywhere: integral_0^R sigma_t exp(-sigma_t s) ds
    // (scattered, weight albedo = 1, of radiance 1 from every direction) plus exp(-sigma_t
    // R) (the emitter) is 1. Each pixel's steady value is an independent estimate of 1.
    // Grey: every scattering weighs exactly albedo = 1, so only light sampling and MIS
    // add noise and the check is tight. Chromatic: the spectral MIS weights of the free
    // flights add much more.
    for (sigma_t, spp, max_se, seed) in [
        ("2, 2, 2", "128", 0.003, 7u64),
        ("1, 2, 4", "256", 0.006, 8),
    ] {
        let xml = FURNACE.replace("SIGMA_T", sigma_t).replace("SPP", spp);
        let scene = load(&xml, &Overrides::default());
        let out = run(&scene, seed);
        let pixels = scene.film.pixels();
        for c in 0..3 {
            let v: Vec<f64> = (0..pixels).map(|p| out.steady[p * 3 + c]).collect();
            let mean = v.iter().sum::<f64>() / pixels as f64;
            let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (pixels - 1) as f64;
            let se = (var / pixels as f64).sqrt();
            eprintln!("sigma_t {sigma_t} channel {c}: {mean:.5} (se {se:.5})");
            assert!(
                (mean - 1.0).abs() < 4.5 * se && se < max_se,
                "sigma_t {sigma_t} channel {c}: {mean} (se {se})"
            );
        }
        assert_eq!(out.dropped_nonfinite, 0);
    }
    let xml = FURNACE.replace("SIGMA_T", "1, 2, 4").replace("SPP", "128");
    let scene = load(&xml, &Overrides::default());
    let out = run(&scene, 9);
    let pixels = scene.film.pixels();
    // Every camera ray starts in the fog: its first interaction is a scattering with
    // probability 1 - exp(-sigma_t), per channel picked uniformly.
    let want: f64 = [1.0f64, 2.0, 4.0]
        .iter()
        .map(|s| {
            // The channel's pick uses the balance of the three: P(scatter) is the
            // average over the picked channel of 1 - exp(-sigma_t,c).
            (1.0 - (-s).exp()) / 3.0
        })
        .sum();
    let frac = out.gbuffer.iter().map(|g| g.medium as f64).sum::<f64>() / pixels as f64;
    let se = (want * (1.0 - want) / (pixels as f64 * scene.spp as f64)).sqrt();
    assert!(
        (frac - want).abs() < 4.5 * se,
        "medium fraction {frac} vs {want}"
    );
}

fn scene_file(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

/// Per-bin image totals of a render and their variances (pixels are independent).
fn bin_totals(scene: &Scene, seed: u64) -> Vec<([f64; 3], [f64; 3])> {
    let out = run(scene, seed);
    let (t_bins, n) = (scene.film.bins, scene.spp as f64);
    (0..t_bins)
        .map(|k| {
            let mut tot = ([0.0; 3], [0.0; 3]);
            for p in 0..scene.film.pixels() {
                for c in 0..3 {
                    let v = (p * t_bins + k) * 3 + c;
                    let mean = out.accum.x1[v] / n;
                    let var = (out.accum.x2[v] / n - mean * mean).max(0.0) * n / (n - 1.0);
                    tot.0[c] += mean;
                    tot.1[c] += var / n;
                }
            }
            tot
        })
        .collect()
}

#[test]
fn a_vanishing_fog_renders_the_scene_without_it() {
    let o = Overrides {
        width: Some(16),
        spp: Some(256),
        bins: Some(24),
        start_opl: Some(3.0),
        bin_width_opl: Some(0.5),
        max_depth: Some(4),
        defaults: vec![("sigma_t".into(), "1e-4".into())],
        ..Default::default()
    };
    let fog = Scene::load(&scene_file("cbox_fog.xml"), &o).unwrap();
    assert!(fog.integrator.volumetric && !fog.media.is_empty());
    let plain = Scene::load(
        &scene_file("cbox.xml"),
        &Overrides {
            defaults: Vec::new(),
            ..o
        },
    )
    .unwrap();
    assert!(!plain.integrator.volumetric);
    let (a, b) = (bin_totals(&fog, 1), bin_totals(&plain, 2));
    let mut checked = 0;
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        for c in 0..3 {
            let se = (x.1[c] + y.1[c]).sqrt();
            if y.0[c] == 0.0 && x.0[c] == 0.0 {
                continue;
            }
            checked += 1;
            let z = (x.0[c] - y.0[c]) / se;
            assert!(
                z.abs() < 4.5,
                "bin {k} channel {c}: fog {} vs none {} (z = {z:.2})",
                x.0[c],
                y.0[c]
            );
        }
    }
    assert!(checked > 30, "only {checked} bins hold light");
}

#[test]
fn a_dense_fog_changes_the_render_and_records_where_paths_scatter_first() {
    // The counterpart of the test above: the comparison can fail. With sigma_t = 2 the
    // walls fade and the fog holds most first interactions.
    let o = Overrides {
        width: Some(8),
        spp: Some(16),
        defaults: vec![("sigma_t".into(), "2".into())],
        ..Default::default()
    };
    let fog = Scene::load(&scene_file("cbox_fog.xml"), &o).unwrap();
    let out = run(&fog, 3);
    let medium: f64 = out.gbuffer.iter().map(|g| g.medium as f64).sum::<f64>() / 64.0;
    // Grazing rays near the image's edges meet the walls and the floor soon; through
    // the centre the fog is 2 units deep (a scattering with probability 1 - e^-4).
    let centre: f64 = (2..6)
        .flat_map(|y| (2..6).map(move |x| y * 8 + x))
        .map(|p| out.gbuffer[p].medium as f64)
        .sum::<f64>()
        / 16.0;
    assert!(
        medium > 0.5 && centre > 0.9,
        "medium fraction {medium}, centre {centre}"
    );
    let clear = Scene::load(
        &scene_file("cbox.xml"),
        &Overrides {
            defaults: Vec::new(),
            ..o
        },
    )
    .unwrap();
    let out = run(&clear, 3);
    assert!(out.gbuffer.iter().all(|g| g.medium == 0.0));
}

#[test]
fn transient_path_refuses_scenes_with_media() {
    let text = std::fs::read_to_string(scene_file("cbox_fog.xml"))
        .unwrap()
        .replace("transient_prbvolpath", "transient_path");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.xml");
    std::fs::write(&path, text).unwrap();
    let e = Scene::load(&path, &Overrides::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("<medium") && e.contains("transient_prbvolpath") && !e.contains('\n'),
        "{e}"
    );
}

#[test]
fn bundles_of_media_scenes_record_them_and_merge_the_medium_fraction() {
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_tstat");
    let scene = scene_file("cbox_fog.xml");
    for seed in ["1", "2"] {
        let out = dir.path().join(format!("s{seed}.tstats"));
        let r = Command::new(bin)
            .args([
                "render",
                scene.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ])
            .args(["--spp", "4", "--width", "6", "--bins", "8", "--seed", seed])
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    let merged = dir.path().join("m.tstats");
    let r = Command::new(bin)
        .args(["merge"])
        .args([dir.path().join("s1.tstats"), dir.path().join("s2.tstats")])
        .args(["--out".as_ref(), merged.as_os_str()])
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let open = |p: &Path| tstat::bundle::Bundle::open(p).unwrap();
    let (a, b, m) = (
        open(&dir.path().join("s1.tstats")),
        open(&dir.path().join("s2.tstats")),
        open(&merged),
    );
    assert!(a.manifest.media && m.manifest.media);
    let (fa, fb, fm) = (
        a.medium().unwrap().unwrap(),
        b.medium().unwrap().unwrap(),
        m.medium().unwrap().unwrap(),
    );
    assert_eq!(fa.dim(), (6, 6));
    assert!(fa.iter().any(|&v| v > 0.0) && fa.iter().all(|&v| (0.0..=1.0).contains(&v)));
    for ((x, y), z) in fa.iter().zip(&fb).zip(&fm) {
        assert!((0.5 * (x + y) - z).abs() < 1e-6);
    }
    // A surface-only scene's bundle has neither.
    let plain = dir.path().join("p.tstats");
    let r = Command::new(bin)
        .args(["render", scene_file("cbox.xml").to_str().unwrap(), "--out"])
        .arg(&plain)
        .args(["--spp", "2", "--width", "4", "--bins", "4"])
        .output()
        .unwrap();
    assert!(r.status.success());
    let p = open(&plain);
    assert!(!p.manifest.media && p.medium().unwrap().is_none());
    assert!(!plain.join("medium.npy").exists());
    let text = std::fs::read_to_string(plain.join("manifest.json")).unwrap();
    assert!(!text.contains("\"media\""));
}

const ENV_FURNACE: &str = r#"<scene version="3.0.0">
  <integrator type="transient_prbvolpath"><integer name="max_depth" value="-1"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="128"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="12"/><integer name="height" value="12"/>
      <integer name="temporal_bins" value="1"/>
      <float name="bin_width_opl" value="1000"/>
    </film>
  </sensor>
  <shape type="sphere">
    <bsdf type="null"/>
    <medium type="homogeneous" name="interior">
      <rgb name="sigma_t" value="2"/><float name="albedo" value="1"/>
      <phase type="hg"><float name="g" value="0.5"/></phase>
    </medium>
  </shape>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
</scene>"#;

#[test]
fn a_non_absorbing_fog_under_a_uniform_sky_loses_no_energy() {
    // A sphere of non-absorbing fog under constant radiance 1: the RTE's solution is 1
    // everywhere, so every pixel (fog or sky) estimates 1. Light reaches the fog both
    // by light sampling and by rays that leave the scene (MIS): dropping either, or
    // weighting them wrongly, moves the mean away from 1.
    let scene = load(ENV_FURNACE, &Overrides::default());
    let out = run(&scene, 11);
    let pixels = scene.film.pixels();
    let spp = scene.spp as f64;
    let means: Vec<f64> = (0..pixels).map(|p| out.steady[p * 3]).collect();
    let mean = means.iter().sum::<f64>() / pixels as f64;
    let var = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (pixels as f64 - 1.0);
    let se = (var / pixels as f64).sqrt();
    assert!(se < 0.01, "too noisy to test: se {se}");
    assert!((mean - 1.0).abs() < 4.0 * se + 1e-4, "mean {mean}, se {se}");
    // The transient holds the steady energy (escapes are timed, not dropped).
    let binned: f64 = out.accum.x1.iter().sum::<f64>() / spp;
    let steady: f64 = out.steady.iter().sum::<f64>();
    assert!(
        (binned - steady).abs() <= 1e-9 * steady,
        "{binned} vs {steady}"
    );
}
