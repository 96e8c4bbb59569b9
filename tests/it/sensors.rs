//! The `orthographic` and `thinlens` sensors against closed forms: an orthographic view
//! of a plane perpendicular to it arrives at one OPL in every pixel and spans its
//! to_world extent; a thin lens of (near) zero aperture renders the pinhole's image;
//! a defocused edge follows the circle of confusion's disk-segment profile.

use tstat::render::RenderOutput;
use tstat::scene::Overrides;

use crate::common;
use common::{load, run, PINHOLE};

/// A scene with `sensor` (its inner XML given, film and sampler added) and `shapes`.
fn scene_xml(sensor_type: &str, sensor: &str, film: &str, spp: u32, shapes: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="1"/></integrator>
  <sensor type="{sensor_type}">
    {sensor}
    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
    <film type="transient_hdr_film">{film}</film>
  </sensor>
  {shapes}
</scene>"#
    )
}

/// The steady value of pixel (x, y), channel 0.
fn steady(out: &RenderOutput, w: usize, x: usize, y: usize) -> f64 {
    out.steady[(y * w + x) * 3]
}

const PLANE_AT_3: &str = r#"<shape type="rectangle">
    <transform name="to_world"><scale x="0.9" y="5"/><translate z="-3"/></transform>
    <emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter>
  </shape>"#;

const FILM_16X8: &str = r#"<integer name="width" value="16"/><integer name="height" value="8"/>
    <integer name="temporal_bins" value="10"/>
    <float name="start_opl" value="2.55"/><float name="bin_width_opl" value="0.1"/>"#;

#[test]
fn orthographic_plane_arrives_in_one_bin_across_its_extent() {
    // The view spans local [-1, 1] x [-H/W, H/W] scaled by 2: world x in [-2, 2] over
    // 16 columns; the emitting plane x in [-0.9, 0.9] at distance 3 covers columns 5..10
    // whole, 4 and 11 in part, and nothing else.
    let sensor = r#"<transform name="to_world"><scale x="2" y="2"/>
        <lookat origin="0,0,0" target="0,0,-1" up="0,1,0"/></transform>"#;
    let scene = load(
        &scene_xml("orthographic", sensor, FILM_16X8, 8, PLANE_AT_3),
        &Overrides::default(),
    );
    let out = run(&scene, 1);
    let (w, h, t) = (16, 8, 10);
    // OPL 3 lies in bin floor((3 - 2.55) / 0.1) = 4.
    let bin = 4;
    let mut edge = 0.0;
    for y in 0..h {
        for x in 0..w {
            let v = steady(&out, w, x, y);
            match x {
                5..=10 => assert!((v - 2.0).abs() < 1e-6, "({x}, {y}): {v}"),
                4 | 11 => edge += v,
                _ => assert_eq!(v, 0.0, "({x}, {y})"),
            }
            for k in 0..t {
                let n = out.accum.nonzero[(y * w + x) * t + k];
                if k != bin {
                    assert_eq!(n, 0, "({x}, {y}) bin {k}");
                } else if (5..=10).contains(&x) {
                    assert_eq!(n, scene.spp, "({x}, {y})");
                }
            }
        }
    }
    // Columns 4 and 11 are covered over 0.6 of their width: mean 0.6 L = 1.2 over
    // 16 pixels of 8 binomial samples (standard error 2 sqrt(0.24 / 128) = 0.087).
    let edge = edge / 16.0;
    assert!((edge - 1.2).abs() < 4.0 * 0.087, "{edge}");
    // The G-buffer depth is the distance from the near plane (near_clip 0.01 past the
    // sensor plane, the default time origin): 2.99 everywhere it hits.
    for x in 5..=10 {
        assert!((out.gbuffer[x].depth - 2.99).abs() < 1e-5);
    }
    // The test can fail: a perspective camera at the same place spreads the plane's
    // arrival over several bins (OPL 3 / cos theta).
    let wide = scene_xml(
        "perspective",
        r#"<float name="fov" value="60"/><transform name="to_world"><lookat origin="0,0,0" target="0,0,-1" up="0,1,0"/></transform>"#,
        FILM_16X8,
        8,
        PLANE_AT_3,
    );
    let out = run(&load(&wide, &Overrides::default()), 1);
    let lit_bins = (0..t)
        .filter(|&k| (0..w * h).any(|p| out.accum.nonzero[p * t + k] > 0))
        .count();
    assert!(lit_bins > 1);
}

#[test]
fn thin_lens_of_zero_aperture_renders_the_pinhole_image() {
    // Mitsuba turns aperture 0 into 2^-24: the rays leave within 6e-8 of the pinhole,
    // towards the same focal point, and every other random number of a path is the
    // pinhole path's (the aperture has its own stream). So the images agree to float
    // rounding except where a ray's last-bit change moves it across an edge.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let text = std::fs::read_to_string(&path).unwrap();
    let lens = text.replacen(
        r#"<sensor type="perspective">"#,
        r#"<sensor type="thinlens"><float name="aperture_radius" value="0"/><float name="focus_distance" value="3.9"/>"#,
        1,
    );
    assert_ne!(lens, text);
    let o = Overrides {
        width: Some(24),
        height: Some(24),
        spp: Some(8),
        ..Default::default()
    };
    let (a, b) = (load(&text, &o), load(&lens, &o));
    assert!(b.warnings.iter().any(|w| w.contains("2^-24")));
    let (a, b) = (run(&a, 7), run(&b, 7));
    let n = a.steady.len();
    let mut same = 0;
    let (mut sa, mut sb) = (0.0, 0.0);
    for i in 0..n {
        let (x, y) = (a.steady[i], b.steady[i]);
        sa += x;
        sb += y;
        if (x - y).abs() <= 1e-4 * x.abs().max(1e-3) {
            same += 1;
        }
    }
    eprintln!("zero aperture: {same} of {n} values within 1e-4, means {sa} vs {sb}");
    // Nearly every pixel agrees to 1e-4 relative; the few whose paths crossed an
    // edge differ by Monte Carlo noise only, and the image means agree to 0.1 %.
    assert!(same * 100 >= n * 97, "{same} of {n} pixel values agree");
    assert!((sa - sb).abs() <= 1e-3 * sa, "{sa} vs {sb}");
    // The depth buffer: the lens point is within 6e-8 of the pinhole.
    for (p, q) in a.gbuffer.iter().zip(&b.gbuffer) {
        assert!((p.depth - q.depth).abs() <= 1e-4 * p.depth.max(1.0));
    }
}

/// The fraction of the unit disk with x < h (h in [-1, 1]): a disk segment.
fn disk_fraction_below(h: f64) -> f64 {
    let h = h.clamp(-1.0, 1.0);
    0.5 + (h * (1.0 - h * h).sqrt() + h.asin()) / std::f64::consts::PI
}

#[test]
fn thin_lens_defocuses_an_edge_over_the_circle_of_confusion() {
    // Lens at the origin looking down -z, aperture A, focus F; an emitting half-plane
    // (world x > 0) at depth Z < F. The ray from lens point a (camera space) through
    // the focal point F (sx, sy, 1) is at a (1 - Z / F) + Z (sx, sy) at depth Z; camera
    // +x is world -x, so it hits the half-plane when a_x < -sx Z F / (F - Z): the pixel
    // sees L times the fraction of the lens disk left of that line, a disk segment of
    // half-width c = A (F - Z) / (Z F) in sx, the circle of confusion's radius.
    let (a, f, z, l) = (0.05f64, 4.0f64, 2.0f64, 1.5f64);
    let c = a * (f - z) / (z * f);
    let (w, h, spp) = (48usize, 2usize, 2048u32);
    let tan_half = 1.5 * c; // the image spans +-1.5 c: the blur and flat parts on both sides
    let fov = 2.0 * tan_half.atan().to_degrees();
    let sensor = format!(
        r#"<float name="fov" value="{fov}"/><float name="aperture_radius" value="{a}"/>
        <float name="focus_distance" value="{f}"/>
        <transform name="to_world"><lookat origin="0,0,0" target="0,0,-1" up="0,1,0"/></transform>"#
    );
    let film = format!(
        r#"<integer name="width" value="{w}"/><integer name="height" value="{h}"/>
        <integer name="temporal_bins" value="4"/><float name="start_opl" value="0"/><float name="bin_width_opl" value="1"/>"#
    );
    let shapes = format!(
        r#"<shape type="rectangle">
        <transform name="to_world"><scale value="10"/><translate x="10" z="-{z}"/></transform>
        <emitter type="area"><rgb name="radiance" value="{l}, {l}, {l}"/></emitter>
      </shape>"#
    );
    // OPL from the lens (the near-clip origin is tested below).
    let scene = load(
        &scene_xml("thinlens", &sensor, &film, spp, &shapes),
        &PINHOLE,
    );
    let out = run(&scene, 3);
    let n = spp as f64;
    let mut interior = 0;
    for y in 0..h {
        for x in 0..w {
            // The expected value: the segment fraction averaged over the pixel's
            // footprint (x + u, u uniform; sx = (1 - 2 (x + u) / W) tan_half).
            let grid = 2000;
            let want = l
                * (0..grid)
                    .map(|i| {
                        let sx = (1.0
                            - 2.0 * (x as f64 + (i as f64 + 0.5) / grid as f64) / w as f64)
                            * tan_half;
                        disk_fraction_below(-sx / c)
                    })
                    .sum::<f64>()
                / grid as f64;
            let got = steady(&out, w, x, y);
            let p = want / l;
            // Binomial standard error of the mean of spp hits of weight L.
            let se = l * (p * (1.0 - p) / n).sqrt();
            assert!(
                (got - want).abs() <= 5.0 * se + 1e-6 * l,
                "pixel ({x}, {y}): {got} vs {want} (se {se})"
            );
            if p > 0.05 && p < 0.95 {
                interior += 1;
            }
        }
    }
    // The blur covers 2 c of the 3 c the image spans: about 2/3 of the columns, less
    // the flat ends of the segment profile.
    assert!(interior >= 2 * w / 2, "{interior}");
    // Every ray travels from the lens to the plane: OPL Z / cos, in bin 2 (Z = 2).
    let t = scene.film.time.bins;
    for p in 0..w * h {
        for k in [0, 1, 3] {
            assert_eq!(out.accum.nonzero[p * t + k], 0);
        }
    }
}

/// The temporal Gaussian (`temporal_filter` gaussian) on the plane that arrives at one
/// OPL: every lit pixel's transient is its radiance times the filter's shares around
/// OPL 3, computed here from Mitsuba's Gaussian by its definition; each lit bin gets
/// one sample per path; the steady image keeps the box's bits.
#[test]
fn temporal_gaussian_splits_one_arrival_over_its_neighbouring_bins() {
    let sensor = r#"<transform name="to_world"><scale x="2" y="2"/>
        <lookat origin="0,0,0" target="0,0,-1" up="0,1,0"/></transform>"#;
    let boxed = scene_xml("orthographic", sensor, FILM_16X8, 8, PLANE_AT_3);
    let sd = 1.3;
    let gauss = boxed.replace(
        r#"<integer name="max_depth" value="1"/>"#,
        &format!(
            r#"<integer name="max_depth" value="1"/><string name="temporal_filter" value="gaussian"/><float name="gaussian_stddev" value="{sd}"/>"#
        ),
    );
    // OPL from the sensor plane: the arrival at the centre of bin 4.
    let (b, g) = (
        run(&load(&boxed, &PINHOLE), 1),
        run(&load(&gauss, &PINHOLE), 1),
    );
    assert_eq!(b.steady, g.steady);
    let (w, t) = (16, 10);
    // OPL 3 sits at tau = (3 - 2.55) / 0.1 = 4.5 bins: the centre of bin 4.
    let tau = 4.5;
    let r: f64 = 4.0 * sd;
    let weight = |x: f64| {
        if x.abs() < r {
            (-x * x / (2.0 * sd * sd)).exp() - (-r * r / (2.0 * sd * sd)).exp()
        } else {
            0.0
        }
    };
    let total: f64 = (-50..50).map(|k| weight(k as f64 + 0.5 - tau)).sum();
    let share: Vec<f64> = (0..t)
        .map(|k| weight(k as f64 + 0.5 - tau) / total)
        .collect();
    // The support (|x| < 5.2 bins) reaches bins 0..=9 from the centre of bin 4: all
    // of it lies in the window but bin 10's share, which is lost.
    assert!(share.iter().all(|&s| s > 0.0));
    let y = 3;
    for x in 5..=10 {
        let p = y * w + x;
        for (c, radiance) in [2.0, 3.0, 4.0].into_iter().enumerate() {
            for (k, s) in share.iter().enumerate() {
                let got = g.accum.x1[((p * t) + k) * 3 + c] / 8.0;
                assert!(
                    (got - radiance * s).abs() < 1e-6 * radiance,
                    "({x}, {y}) bin {k} channel {c}: {got} vs {}",
                    radiance * s
                );
            }
        }
        for k in 0..t {
            assert_eq!(g.accum.nonzero[p * t + k], 8, "bin {k}");
        }
    }
    // The box puts it all in bin 4: the test can tell them apart.
    assert_eq!(b.accum.nonzero[(y * w + 5) * t + 3], 0);
}

/// The time origin (SPEC 2, `sensors/time_origin.rs`): by default OPL counts from the
/// near-clip plane, so a plane 3 away seen through a near_clip of 1 arrives at OPL
/// 2 / cos(theta), and something nearer than the near plane is not seen (as Mitsuba);
/// `--time-origin pinhole` counts from the pinhole (3 / cos(theta)) and sees it.
#[test]
fn the_near_clip_plane_is_the_default_time_origin() {
    use tstat::sensors::time_origin::TimeOrigin;
    let film = r#"<integer name="width" value="8"/><integer name="height" value="8"/>
    <integer name="temporal_bins" value="12"/>
    <float name="start_opl" value="1.95"/><float name="bin_width_opl" value="0.1"/>"#;
    // An occluder 0.5 in front of the camera over the middle of the view.
    let shapes = format!(
        r#"{PLANE_AT_3}<shape type="rectangle">
    <transform name="to_world"><scale x="0.02" y="0.02"/><translate z="-0.5"/></transform>
  </shape>"#
    );
    let sensor = r#"<float name="fov" value="10"/><float name="near_clip" value="1"/>
        <transform name="to_world"><lookat origin="0,0,0" target="0,0,-1" up="0,1,0"/></transform>"#;
    let xml = scene_xml("perspective", sensor, film, 16, &shapes);
    let (w, t) = (8, 12);
    let lit_bins = |o: &Overrides| {
        let scene = load(&xml, o);
        let out = run(&scene, 1);
        let bins: Vec<usize> = (0..t)
            .filter(|&k| (0..w * w).any(|p| out.accum.nonzero[p * t + k] > 0))
            .collect();
        let centre = (0..t)
            .map(|k| out.accum.nonzero[(4 * w + 4) * t + k])
            .sum::<u32>();
        (scene.camera.time_origin(), bins, centre, out)
    };
    // theta <= 5 degrees * sqrt(2): 2 / cos in [2, 2.0096], bin 0.
    let (origin, bins, centre, out) = lit_bins(&Overrides::default());
    assert_eq!(origin, TimeOrigin::NearClip);
    assert_eq!(bins, [0]);
    assert_eq!(centre, 16, "the occluder before the near plane is not seen");
    // The depth is measured from where the ray starts: 2 at the centre.
    assert!((out.gbuffer[4 * w + 4].depth - 2.0).abs() < 0.01);
    // 3 / cos in [3, 3.0144]: bin 10; the occluder hides the centre pixel.
    let (origin, bins, centre, _) = lit_bins(&PINHOLE);
    assert_eq!(origin, TimeOrigin::Pinhole);
    assert_eq!(bins, [10]);
    assert_eq!(centre, 0);
}
