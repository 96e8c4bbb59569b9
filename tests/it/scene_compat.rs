//! Mitsuba 3 scene-file features that public scenes rely on: `<include>`, `<path>`,
//! `focal_length`, `focus_distance`, mitransient's `temporal_filter`.

use std::path::Path;
use tstat::render::{render, PixelSampling, RenderSettings};
use tstat::scene::check::{check, Verdict};
use tstat::scene::{Overrides, Scene};
use tstat::sensors::time_filter::TimeFilter;
use tstat::stats::Transform;

const HEAD: &str = r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
  <sensor type="perspective">
    SENSOR
    <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="8"/><integer name="height" value="6"/>
      <integer name="temporal_bins" value="10"/>
      <float name="start_opl" value="3"/><float name="bin_width_opl" value="0.5"/>
    </film>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="3"/><rgb name="intensity" value="5"/></emitter>
"#;

const FOV: &str = r#"<float name="fov" value="40"/>"#;

const SHAPES: &str = r#"<bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.4"/></bsdf>
  <shape type="rectangle"><ref id="grey"/></shape>
  <shape type="ply"><string name="filename" value="tri.ply"/><ref id="grey"/></shape>
"#;

const TRI_PLY: &str =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
    property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
    -0.5 -0.5 0.5\n0.5 -0.5 0.5\n0 0.5 0.5\n3 0 1 2\n";

fn write(dir: &Path, name: &str, text: &str) {
    let p = dir.join(name);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, text).unwrap();
}

fn scene(sensor: &str, body: &str) -> String {
    format!("{}{body}</scene>", HEAD.replace("SENSOR", sensor))
}

fn load(dir: &Path, name: &str) -> Result<Scene, String> {
    Scene::load(&dir.join(name), &Overrides::default()).map_err(|e| e.to_string())
}

/// The error of a scene that must not load.
fn error(dir: &Path, name: &str) -> String {
    match load(dir, name) {
        Ok(_) => panic!("{name} loaded"),
        Err(e) => e,
    }
}

fn steady(s: &Scene) -> Vec<f64> {
    let settings = RenderSettings {
        spp: s.spp,
        seed: 1,
        transform: Transform::Identity,
        pixel_sampling: PixelSampling::Independent,
        replicates: 0,
        pixel_spp: None,
    };
    render(s, &settings, &|_| {}).steady
}

#[test]
fn include_and_path_render_the_same_scene_as_written_inline() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    // Inline: the mesh beside the scene.
    write(d, "tri.ply", TRI_PLY);
    write(d, "inline.xml", &scene(FOV, SHAPES));
    // Split: shapes in parts/shapes.xml, the mesh in meshes/ found through <path>.
    write(d, "meshes/tri.ply", TRI_PLY);
    write(
        d,
        "parts/shapes.xml",
        &format!(r#"<scene version="3.0.0">{SHAPES}</scene>"#),
    );
    write(
        d,
        "split/scene.xml",
        &scene(
            FOV,
            r#"<path value="../meshes"/><include filename="../parts/shapes.xml"/>"#,
        ),
    );
    let a = load(d, "inline.xml").unwrap();
    let b = load(&d.join("split"), "scene.xml").unwrap();
    assert_eq!(a.shapes.len(), b.shapes.len());
    assert_eq!(steady(&a), steady(&b));
    // The mesh file read is the one under meshes/.
    assert!(
        b.mesh_files.iter().any(|f| f.ends_with("meshes/tri.ply")),
        "{:?}",
        b.mesh_files
    );
}

#[test]
fn a_later_path_wins_and_the_scene_folder_comes_last() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    // Two candidates: a broken one beside the scene, a good one under good/.
    write(d, "tri.ply", "not a ply");
    write(d, "good/tri.ply", TRI_PLY);
    write(
        d,
        "s.xml",
        &scene(FOV, &format!(r#"<path value="good"/>{SHAPES}"#)),
    );
    assert!(load(d, "s.xml").is_ok());
    write(d, "t.xml", &scene(FOV, SHAPES));
    // Without the <path>, the broken tri.ply beside the scene is the one read.
    let e = error(d, "t.xml");
    let want = format!(
        "invalid PLY file {}: not a PLY file",
        d.join("tri.ply").display()
    );
    assert!(e.contains(&want), "{e}");
}

#[test]
fn bad_includes_and_paths_are_one_clear_error() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let cases = [
        (
            r#"<include filename="missing.xml"/>"#,
            "cannot read included file",
        ),
        (
            r#"<path value="no/such/folder"/>"#,
            "folder 'no/such/folder' not found",
        ),
        (r#"<include filename="self.xml"/>"#, "includes itself"),
        (
            r#"<include filename="notscene.xml"/>"#,
            "<foo> is not supported (supported at top level",
        ),
        (r#"<include filename="broken.xml"/>"#, "malformed XML"),
    ];
    write(
        d,
        "self.xml",
        r#"<scene version="3.0.0"><include filename="self.xml"/></scene>"#,
    );
    write(d, "notscene.xml", "<foo/>");
    write(d, "broken.xml", "<scene><shape></scene>");
    for (body, want) in cases {
        write(d, "s.xml", &scene(FOV, &format!("{body}{SHAPES}")));
        let e = error(d, "s.xml");
        assert!(e.contains(want), "{body}: {e}");
    }
}

#[test]
fn focal_length_gives_mitsubas_field_of_view() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    // Mitsuba: fov = 2 atan(sqrt(36^2 + 24^2) / (2 f)) on the diagonal; 50mm default.
    let diag_fov = |f: f64| {
        2.0 * ((36.0f64 * 36.0 + 24.0 * 24.0).sqrt() / (2.0 * f))
            .atan()
            .to_degrees()
    };
    for (sensor, f) in [
        ("", 50.0),
        (r#"<string name="focal_length" value="35mm"/>"#, 35.0),
    ] {
        write(d, "a.xml", &scene(sensor, SHAPES));
        write(
            d,
            "b.xml",
            &scene(
                &format!(
                    r#"<float name="fov" value="{}"/><string name="fov_axis" value="diagonal"/>"#,
                    diag_fov(f)
                ),
                SHAPES,
            ),
        );
        let (a, b) = (load(d, "a.xml").unwrap(), load(d, "b.xml").unwrap());
        assert_eq!(a.camera.tan_half, b.camera.tan_half, "{f} mm");
    }
    // focus_distance has no effect on a pinhole.
    write(
        d,
        "c.xml",
        &scene(
            &format!(r#"{FOV}<float name="focus_distance" value="3"/>"#),
            SHAPES,
        ),
    );
    write(d, "d.xml", &scene(FOV, SHAPES));
    assert_eq!(
        load(d, "c.xml").unwrap().camera.tan_half,
        load(d, "d.xml").unwrap().camera.tan_half
    );
    for (sensor, want) in [
        (
            format!(r#"{FOV}<string name="focal_length" value="50mm"/>"#),
            "either 'fov' or 'focal_length'",
        ),
        (
            r#"<string name="focal_length" value="wide"/>"#.to_string(),
            "focal_length 'wide'",
        ),
        (
            format!(r#"{FOV}<float name="principal_point_offset_x" value="0.1"/>"#),
            "principal point",
        ),
    ] {
        write(d, "e.xml", &scene(&sensor, SHAPES));
        let e = error(d, "e.xml");
        assert!(e.contains(want), "{e}");
    }
}

#[test]
fn temporal_filter_is_accepted_as_mitransient_does() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let with = |filter: &str| {
        scene(FOV, SHAPES).replace(
            r#"<integer name="max_depth" value="3"/>"#,
            &format!(r#"<integer name="max_depth" value="3"/>{filter}"#),
        )
    };
    write(
        d,
        "box.xml",
        &with(
            r#"<string name="temporal_filter" value="box"/><float name="gaussian_stddev" value="2"/>"#,
        ),
    );
    assert!(load(d, "box.xml").is_ok());
    // The Gaussian loads as asked, without a warning; its default stddev is 2 bins.
    write(
        d,
        "g.xml",
        &with(
            r#"<string name="temporal_filter" value="gaussian"/><float name="gaussian_stddev" value="0.5"/>"#,
        ),
    );
    let g = load(d, "g.xml").unwrap();
    assert!(g.warnings.is_empty(), "{:?}", g.warnings);
    assert_eq!(
        g.integrator.time_filter,
        TimeFilter::Gaussian { stddev: 0.5 }
    );
    write(
        d,
        "g2.xml",
        &with(r#"<string name="temporal_filter" value="gaussian"/>"#),
    );
    assert_eq!(
        load(d, "g2.xml").unwrap().integrator.time_filter,
        TimeFilter::Gaussian { stddev: 2.0 }
    );
    assert_eq!(
        load(d, "box.xml").unwrap().integrator.time_filter,
        TimeFilter::Box
    );
    write(
        d,
        "x.xml",
        &with(r#"<string name="temporal_filter" value="tent"/>"#),
    );
    assert!(error(d, "x.xml").contains("'tent' is not one of: box, gaussian"));
    write(
        d,
        "n.xml",
        &with(
            r#"<string name="temporal_filter" value="gaussian"/><float name="gaussian_stddev" value="-1"/>"#,
        ),
    );
    assert!(error(d, "n.xml").contains("gaussian_stddev must be positive"));
    write(
        d,
        "w.xml",
        &with(
            r#"<string name="temporal_filter" value="gaussian"/><float name="gaussian_stddev" value="1e9"/>"#,
        ),
    );
    assert!(error(d, "w.xml").contains("at most 64 bins"));
}

#[test]
fn spectra_become_mitsubas_rgb_and_bad_ones_are_clear_errors() {
    use tstat::materials::Bsdf;
    use tstat::scene::spectrum::{list_to_srgb, uniform_to_srgb, SpectrumUse};
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    write(d, "r.spd", "# a reflectance\n400 0.2\n550 0.6\n700 0.4\n");
    let with = |refl: &str, light: &str| {
        scene(FOV, SHAPES)
            .replace(r#"<rgb name="reflectance" value="0.4"/>"#, refl)
            .replace(r#"<rgb name="intensity" value="5"/>"#, light)
    };
    write(
        d,
        "s.xml",
        &with(
            r#"<spectrum name="reflectance" value="400:0.2, 550:0.6, 700:0.4"/>"#,
            r#"<spectrum name="intensity" value="2"/>"#,
        ),
    );
    let s = load(d, "s.xml").unwrap();
    let want = list_to_srgb(
        &[400.0, 550.0, 700.0],
        &[0.2, 0.6, 0.4],
        SpectrumUse::Reflectance,
    )
    .0;
    let Bsdf::Diffuse(diffuse) = &s.bsdfs[0].bsdf else {
        panic!("{:?}", s.bsdfs[0].bsdf)
    };
    assert_eq!(diffuse.reflectance.to_array(), want);
    let tstat::lights::Emitter::Point { intensity, .. } = &s.emitters[0] else {
        panic!()
    };
    assert_eq!(
        intensity.to_array(),
        uniform_to_srgb(2.0, SpectrumUse::Emission)
    );
    // The same spectrum from a file.
    write(
        d,
        "f.xml",
        &with(
            r#"<spectrum name="reflectance" filename="r.spd"/>"#,
            r#"<rgb name="intensity" value="5"/>"#,
        ),
    );
    let f = load(d, "f.xml").unwrap();
    assert_eq!(f.bsdfs[0].bsdf, s.bsdfs[0].bsdf);
    for (refl, want) in [
        (
            r#"<spectrum name="reflectance" value="500:0.2, 400:0.3"/>"#,
            "must increase",
        ),
        (
            r#"<spectrum name="reflectance" value="500:0.2"/>"#,
            "at least two",
        ),
        (
            r#"<spectrum name="reflectance" value="500-0.2, 600:1"/>"#,
            "not a wavelength:value pair",
        ),
        (
            r#"<spectrum name="reflectance" value="500:x, 600:1"/>"#,
            "value in '500:x'",
        ),
        (
            r#"<spectrum name="reflectance" filename="none.spd"/>"#,
            "cannot read spectrum file",
        ),
    ] {
        write(
            d,
            "e.xml",
            &with(refl, r#"<rgb name="intensity" value="5"/>"#),
        );
        let e = error(d, "e.xml");
        assert!(e.contains(want), "{refl}: {e}");
    }
}

#[test]
fn area_emitters_declared_at_top_level_attach_by_reference_also_forward() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let lamp = r#"<shape type="rectangle"><transform name="to_world"><translate z="2"/><rotate x="1" angle="180"/></transform>EMIT</shape>"#;
    let inline = lamp.replace(
        "EMIT",
        r#"<emitter type="area"><rgb name="radiance" value="3"/></emitter>"#,
    );
    let by_ref = lamp.replace("EMIT", r#"<ref id="lamp"/>"#);
    let decl = r#"<emitter type="area" id="lamp"><rgb name="radiance" value="3"/></emitter>"#;
    write(d, "a.xml", &scene(FOV, &format!("{SHAPES}{inline}")));
    write(d, "b.xml", &scene(FOV, &format!("{SHAPES}{decl}{by_ref}")));
    write(d, "c.xml", &scene(FOV, &format!("{SHAPES}{by_ref}{decl}")));
    let (a, b, c) = (
        load(d, "a.xml").unwrap(),
        load(d, "b.xml").unwrap(),
        load(d, "c.xml").unwrap(),
    );
    assert_eq!(a.emitters.len(), 2);
    assert_eq!(steady(&a), steady(&b));
    assert_eq!(steady(&a), steady(&c));
    write(
        d,
        "e.xml",
        &scene(
            FOV,
            &format!("{SHAPES}{}", decl.replace(r#" id="lamp""#, "")),
        ),
    );
    assert!(error(d, "e.xml").contains("needs an id"));
    // No radiance: Mitsuba's default 1, the same render as radiance 1 written out.
    let one = lamp.replace(
        "EMIT",
        r#"<emitter type="area"><rgb name="radiance" value="1"/></emitter>"#,
    );
    let bare = lamp.replace("EMIT", r#"<emitter type="area"/>"#);
    write(d, "one.xml", &scene(FOV, &format!("{SHAPES}{one}")));
    write(d, "bare.xml", &scene(FOV, &format!("{SHAPES}{bare}")));
    let (one, bare) = (load(d, "one.xml").unwrap(), load(d, "bare.xml").unwrap());
    assert_eq!(steady(&one), steady(&bare));
    let radiance = |s: &Scene| match &s.emitters[1] {
        tstat::lights::Emitter::Area { radiance, .. } => *radiance,
        _ => panic!("not an area light"),
    };
    assert_eq!(radiance(&bare), glam::Vec3::ONE);
    assert_eq!(radiance(&a), glam::Vec3::splat(3.0));
}

#[test]
fn d_sets_parameters_the_file_uses_without_a_default() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let xml = scene(FOV, SHAPES).replace(
        r#"<integer name="sample_count" value="4"/>"#,
        r#"<integer name="sample_count" value="$spp"/>"#,
    );
    write(d, "s.xml", &xml);
    assert!(error(d, "s.xml").contains("'$spp' has no <default"));
    let o = |k: &str| Overrides {
        defaults: vec![(k.to_string(), "6".to_string())],
        ..Default::default()
    };
    let s = Scene::load(&d.join("s.xml"), &o("spp")).unwrap();
    assert_eq!(s.spp, 6);
    // A name the file never uses is a typo.
    let e = Scene::load(&d.join("s.xml"), &o("sp"))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("never uses $sp"), "{e}");
}

#[test]
fn check_lists_every_unsupported_feature_with_its_line() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let body = format!(
        "{SHAPES}\n<emitter type=\"sunsky\"/>\n<bsdf type=\"hair\" id=\"p\"/>\n<medium type=\"rayleigh_fog\" id=\"fog\"/>\n"
    );
    write(d, "s.xml", &scene(FOV, &body));
    let Verdict::Unsupported(found) = check(&d.join("s.xml"), &[], &[]) else {
        panic!("not flagged")
    };
    let text: Vec<String> = found.iter().map(|f| f.to_string()).collect();
    assert_eq!(found.len(), 3, "{text:?}");
    assert!(
        text[0].contains("sunsky") && text[1].contains("hair") && text[2].contains("rayleigh_fog"),
        "{text:?}"
    );
    // Lines of the file: the body starts after the 14-line head.
    let lines: Vec<u32> = found.iter().map(|f| f.line).collect();
    assert!(lines.windows(2).all(|w| w[1] == w[0] + 1), "{lines:?}");
    // Through an include too.
    write(
        d,
        "part.xml",
        r#"<scene version="3.0.0"><shape type="ellipsoids"/></scene>"#,
    );
    write(
        d,
        "i.xml",
        &scene(FOV, &format!(r#"{SHAPES}<include filename="part.xml"/>"#)),
    );
    let Verdict::Unsupported(found) = check(&d.join("i.xml"), &[], &[]) else {
        panic!()
    };
    assert!(found[0].file.ends_with("part.xml") && found[0].what.contains("ellipsoids"));
    // A supported scene that still fails says why; a good one is ok.
    write(
        d,
        "f.xml",
        &scene(FOV, &SHAPES.replace("tri.ply", "missing.ply")),
    );
    assert!(
        matches!(check(&d.join("f.xml"), &[], &[]), Verdict::Fails(e) if e.contains("missing.ply"))
    );
    write(d, "g.xml", &scene(FOV, SHAPES));
    assert!(matches!(check(&d.join("g.xml"), &[], &[]), Verdict::Ok(_)));
    // Every bundled scene checks ok.
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for e in std::fs::read_dir(scenes).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "xml") {
            assert!(
                matches!(check(&p, &[], &[]), Verdict::Ok(_)),
                "{}",
                p.display()
            );
        }
    }
}

#[test]
fn a_spot_light_is_a_point_light_inside_its_beam_and_dark_outside() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let point = r#"<emitter type="point"><point name="position" x="0" y="0" z="3"/><rgb name="intensity" value="5"/></emitter>"#;
    // The spot at the same place shines along -z (towards the shapes).
    let spot = |cutoff: f64| {
        format!(
            r#"<emitter type="spot"><transform name="to_world"><lookat origin="0,0,3" target="0,0,0" up="0,1,0"/></transform><rgb name="intensity" value="5"/><float name="cutoff_angle" value="{cutoff}"/><float name="beam_width" value="{}"/></emitter>"#,
            cutoff * 0.99
        )
    };
    let a = scene(FOV, SHAPES);
    assert!(a.contains(point));
    write(d, "p.xml", &a);
    write(d, "s.xml", &a.replace(point, &spot(80.0)));
    write(d, "n.xml", &a.replace(point, &spot(8.0)));
    let p = steady(&load(d, "p.xml").unwrap());
    // Everything visible lies within 40 degrees of the axis: the same light.
    assert_eq!(p, steady(&load(d, "s.xml").unwrap()));
    // An 8-degree beam lights only the middle.
    let n = steady(&load(d, "n.xml").unwrap());
    let (sp, sn): (f64, f64) = (p.iter().sum(), n.iter().sum());
    assert!(sn > 0.0 && sn < 0.3 * sp, "{sn} vs {sp}");
    write(d, "e.xml", &a.replace(point, &spot(0.0)));
    assert!(error(d, "e.xml").contains("cutoff_angle must be in (0, 180]"));
}

#[test]
fn samplers_declared_at_top_level_and_capitalised_booleans_load() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let xml = scene(FOV, SHAPES)
        .replace(
            r#"<sampler type="independent"><integer name="sample_count" value="4"/></sampler>"#,
            r#"<ref id="s"/>"#,
        )
        .replace(
            r#"<scene version="3.0.0">"#,
            r#"<scene version="3.0.0"><sampler type="independent" id="s"><integer name="sample_count" value="7"/><integer name="seed" value="3"/></sampler>"#,
        )
        .replace(
            r#"<integer name="max_depth" value="3"/>"#,
            r#"<integer name="max_depth" value="3"/><boolean name="hide_emitters" value="True"/>"#,
        );
    write(d, "s.xml", &xml);
    let s = load(d, "s.xml").unwrap();
    assert_eq!((s.spp, s.seed), (7, 3));
    assert!(s.integrator.hide_emitters);
    write(d, "e.xml", &xml.replace(r#" id="s">"#, ">"));
    assert!(error(d, "e.xml").contains("a top-level <sampler> needs an id"));
}

#[test]
fn an_included_file_finds_its_includes_through_the_scene_folder_as_mitsuba_does() {
    // Mitsuba's test scenes: main.xml includes "include/base.xml", which includes
    // "include/preamble.xml" -- a name relative to the scene's folder, not to
    // include/ (there is no include/include/). Both the load and `check` find it.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    write(
        d,
        "include/preamble.xml",
        r#"<scene version="3.0.0"><bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.4"/></bsdf></scene>"#,
    );
    write(
        d,
        "include/base.xml",
        r#"<scene version="3.0.0"><include filename="include/preamble.xml"/></scene>"#,
    );
    let body = SHAPES.replace(
        r#"<bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.4"/></bsdf>"#,
        r#"<include filename="include/base.xml"/>"#,
    );
    write(d, "main.xml", &scene(FOV, &body));
    write(d, "inline.xml", &scene(FOV, SHAPES));
    let (a, b) = (load(d, "main.xml").unwrap(), load(d, "inline.xml").unwrap());
    assert_eq!(steady(&a), steady(&b));
    assert!(matches!(
        check(&d.join("main.xml"), &[], &[]),
        Verdict::Ok(_)
    ));
}

#[test]
fn discard_direct_light_hides_the_emitters_the_camera_sees() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let light = r#"<shape type="rectangle"><transform name="to_world"><translate z="1"/></transform>
        <bsdf type="diffuse"/><emitter type="area"><rgb name="radiance" value="2"/></emitter></shape>"#;
    let with = |flag: &str| {
        scene(FOV, &format!("{SHAPES}{light}")).replace(
            r#"<integer name="max_depth" value="3"/>"#,
            &format!(r#"<integer name="max_depth" value="3"/>{flag}"#),
        )
    };
    write(d, "plain.xml", &with(""));
    write(
        d,
        "hide.xml",
        &with(r#"<boolean name="hide_emitters" value="true"/>"#),
    );
    write(
        d,
        "discard.xml",
        &with(r#"<boolean name="discard_direct_light" value="true"/>"#),
    );
    let plain = steady(&load(d, "plain.xml").unwrap());
    let hide = steady(&load(d, "hide.xml").unwrap());
    let discard = steady(&load(d, "discard.xml").unwrap());
    assert_eq!(hide, discard);
    // The light fills part of the view: hiding it must change the image.
    assert!(plain.iter().sum::<f64>() > hide.iter().sum::<f64>() + 1.0);
}

#[test]
fn angulararea_attaches_like_area_and_projector_reads_mitsubas_parameters() {
    use tstat::lights::Emitter;
    use tstat::scene::spectrum::{uniform_to_srgb, SpectrumUse};
    use tstat::textures::Texture;
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    // angulararea: inline, or declared at the top level and referenced (before or
    // after), as `area`; mitransient's defaults (radiance 1, cutoff 10, beam = cutoff).
    let lamp = r#"<shape type="rectangle"><transform name="to_world"><translate z="2"/><rotate x="1" angle="180"/></transform>EMIT</shape>"#;
    let emitter =
        r#"<emitter type="angulararea"><float name="cutoff_angle" value="50"/></emitter>"#;
    write(
        d,
        "a.xml",
        &scene(FOV, &format!("{SHAPES}{}", lamp.replace("EMIT", emitter))),
    );
    let decl = emitter.replace(r#"type="angulararea""#, r#"type="angulararea" id="lamp""#);
    let by_ref = lamp.replace("EMIT", r#"<ref id="lamp"/>"#);
    write(d, "b.xml", &scene(FOV, &format!("{SHAPES}{by_ref}{decl}")));
    let (a, b) = (load(d, "a.xml").unwrap(), load(d, "b.xml").unwrap());
    assert_eq!(steady(&a), steady(&b));
    let Emitter::AngularArea {
        radiance, falloff, ..
    } = &a.emitters[1]
    else {
        panic!("{:?}", a.emitters[1])
    };
    assert_eq!(radiance.to_array(), [1.0; 3]);
    assert_eq!(
        (falloff.cutoff, falloff.beam_width),
        (50f32.to_radians(), 50f32.to_radians())
    );
    write(
        d,
        "c.xml",
        &scene(
            FOV,
            &format!(
                "{SHAPES}{}",
                lamp.replace("EMIT", r#"<emitter type="angulararea"/>"#)
            ),
        ),
    );
    let Emitter::AngularArea { falloff, .. } = &load(d, "c.xml").unwrap().emitters[1] else {
        panic!()
    };
    assert_eq!(falloff.cutoff, 10f32.to_radians());
    // projector: a uniform spectrum follows the emission rule; a top-level texture by
    // reference; focal_length instead of fov; scale and to_world.
    let proj = |params: &str| {
        format!(
            r#"<texture type="checkerboard" id="checks"/>{SHAPES}<emitter type="projector">{params}<transform name="to_world"><lookat origin="0,0,3" target="0,0,0" up="0,1,0"/></transform></emitter>"#
        )
    };
    write(
        d,
        "p.xml",
        &scene(
            FOV,
            &proj(r#"<spectrum name="irradiance" value="2"/><float name="fov" value="30"/>"#),
        ),
    );
    let s = load(d, "p.xml").unwrap();
    let Emitter::Projector(p) = &s.emitters[1] else {
        panic!("{:?}", s.emitters[1])
    };
    assert_eq!(
        p.irradiance,
        Texture::Constant(glam::Vec3::from_array(uniform_to_srgb(
            2.0,
            SpectrumUse::Emission
        )))
    );
    assert!((p.inv_tan_half - 1.0 / 15f32.to_radians().tan()).abs() < 1e-5);
    assert!((p.position - glam::Vec3::new(0.0, 0.0, 3.0)).length() < 1e-6);
    assert!((p.axis - glam::Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
    assert_eq!((p.scale, p.aspect), (1.0, 1.0));
    write(
        d,
        "q.xml",
        &scene(
            FOV,
            &proj(
                r#"<ref name="irradiance" id="checks"/><string name="focal_length" value="50mm"/><float name="scale" value="3"/>"#,
            ),
        ),
    );
    let s = load(d, "q.xml").unwrap();
    let Emitter::Projector(p) = &s.emitters[1] else {
        panic!()
    };
    assert!(matches!(p.irradiance, Texture::Checkerboard(_)) && p.scale == 3.0);
    // 50 mm on the diagonal of a square (1 x 1) frustum: tan(fov_x / 2) = (43.27 / 100) / sqrt 2.
    let want = (36f64.hypot(24.0) / 100.0) / 2f64.sqrt();
    assert!((1.0 / p.inv_tan_half as f64 - want).abs() < 1e-6);
    // Two shapes with one id: Mitsuba 3.9.1 refuses it too ("duplicate ID"), e.g.
    // mitransient's examples/test/simple/simple_angular_4light.xml.
    write(
        d,
        "dup.xml",
        &scene(
            FOV,
            &format!(
                "{SHAPES}{decl}{0}{0}",
                by_ref.replace("<shape", r#"<shape id="light""#)
            ),
        ),
    );
    let e = error(d, "dup.xml");
    assert!(e.contains("id 'light' is already used"), "{e}");
}

#[test]
fn legacy_mitransient_time_window_is_checked_and_named_in_a_warning() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let with = |params: &str| {
        scene(FOV, SHAPES).replace(
            r#"<integer name="max_depth" value="3"/>"#,
            &format!(r#"<integer name="max_depth" value="3"/>{params}"#),
        )
    };
    write(
        d,
        "old.xml",
        &with(
            r#"<float name="exposure" value="6.5"/><integer name="initial_time" value="30"/>
               <integer name="temporal_bins" value="400"/><float name="progressive" value="0.25"/>
               <integer name="samples_per_pass" value="8"/>"#,
        ),
    );
    let s = load(d, "old.xml").unwrap();
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(
        s.warnings[0].contains("(400 bins of 6.5 OPL from 195)"),
        "{}",
        s.warnings[0]
    );
    // The film's window is the one used.
    assert_eq!(
        (
            s.film.time.bins,
            s.film.time.start_opl,
            s.film.time.bin_width_opl
        ),
        (10, 3.0, 0.5)
    );
    // progressive and samples_per_pass alone: no warning.
    write(
        d,
        "p.xml",
        &with(r#"<float name="progressive" value="0.25"/>"#),
    );
    assert!(load(d, "p.xml").unwrap().warnings.is_empty());
    for (bad, msg) in [
        (
            r#"<float name="exposure" value="-1"/>"#,
            "exposure (the bin width of mitransient before 1.0) must be positive",
        ),
        (
            r#"<integer name="temporal_bins" value="0"/>"#,
            "temporal_bins must be positive",
        ),
        (
            r#"<float name="progressive" value="-0.5"/>"#,
            "progressive must be >= 0",
        ),
    ] {
        write(d, "bad.xml", &with(bad));
        let e = error(d, "bad.xml");
        assert!(e.contains(msg), "{e}");
    }
}

#[test]
fn search_folders_from_the_command_line_come_after_the_scene_folder() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "common/tri.ply", TRI_PLY);
    write(d, "scenes/s.xml", &scene(FOV, SHAPES));
    let e = error(d, "scenes/s.xml");
    assert!(e.contains("tri.ply"), "{e}");
    let o = Overrides {
        search_paths: vec![d.join("common")],
        ..Overrides::default()
    };
    let with_a = Scene::load(&d.join("scenes/s.xml"), &o).unwrap();
    assert!(matches!(
        check(&d.join("scenes/s.xml"), &[], &[d.join("common")]),
        Verdict::Ok(_)
    ));
    // A mesh beside the scene wins over the -a folder's (Mitsuba prepends the scene's
    // folder): an empty file there is found first and fails.
    write(d, "scenes/tri.ply", "");
    let Err(e) = Scene::load(&d.join("scenes/s.xml"), &o) else {
        panic!("the empty scenes/tri.ply was not read")
    };
    let e = e.to_string();
    let want = format!(
        "invalid PLY file {}: not a PLY file",
        d.join("scenes/tri.ply").display()
    );
    assert!(e.contains(&want), "{e}");
    assert_eq!(with_a.shapes.len(), 2);
}

#[test]
fn plugin_types_ignore_case_as_mitsuba_on_windows_and_macos() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    write(d, "lower.xml", &scene(FOV, SHAPES));
    write(
        d,
        "upper.xml",
        &scene(
            FOV,
            &SHAPES
                .replace(r#"type="rectangle""#, r#"type="Rectangle""#)
                .replace(r#"type="diffuse""#, r#"type="Diffuse""#),
        ),
    );
    assert_eq!(
        steady(&load(d, "upper.xml").unwrap()),
        steady(&load(d, "lower.xml").unwrap())
    );
}

#[test]
fn an_emitter_without_a_bsdf_reflects_nothing_as_in_mitsuba() {
    // Mitsuba's default BSDF is diffuse 0.5, but black on an emitting shape: the lit
    // emitting rectangle shows exactly its radiance, a plain one the point light.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    let lit = r#"<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#;
    write(d, "e.xml", &scene(FOV, lit));
    let s = steady(&load(d, "e.xml").unwrap());
    // The centre pixel (4, 3) of the 8 x 6 film sees the rectangle.
    let centre = &s[(3 * 8 + 4) * 3..(3 * 8 + 4) * 3 + 3];
    assert_eq!(centre, &[1.0, 1.0, 1.0]);
    write(d, "p.xml", &scene(FOV, r#"<shape type="rectangle"/>"#));
    let s = steady(&load(d, "p.xml").unwrap());
    assert!(s[(3 * 8 + 4) * 3] > 0.05, "{}", s[(3 * 8 + 4) * 3]);
}

#[test]
fn an_included_files_defaults_hold_in_it_and_the_including_scene_wins() {
    // Mitsuba adds an included file's <default>s to its parameters unless set already.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    write(
        d,
        "parts/integrator.xml",
        r#"<scene version="3.0.0"><default name="depth" value="2"/>
           <integrator type="transient_path"><integer name="max_depth" value="$depth"/></integrator></scene>"#,
    );
    let body = format!(r#"<include filename="parts/integrator.xml"/>{SHAPES}"#);
    let head = HEAD.replace(
        r#"<integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>"#,
        "",
    );
    let text = format!("{}{body}</scene>", head.replace("SENSOR", FOV));
    write(d, "s.xml", &text);
    assert_eq!(load(d, "s.xml").unwrap().integrator.max_depth, 2);
    // The including scene's default wins over the included file's.
    write(
        d,
        "t.xml",
        &text.replace(
            r#"<scene version="3.0.0">"#,
            r#"<scene version="3.0.0"><default name="depth" value="5"/>"#,
        ),
    );
    assert_eq!(load(d, "t.xml").unwrap().integrator.max_depth, 5);
    // And -D over both.
    let o = Overrides {
        defaults: vec![("depth".into(), "4".into())],
        ..Overrides::default()
    };
    assert_eq!(
        Scene::load(&d.join("t.xml"), &o)
            .unwrap()
            .integrator
            .max_depth,
        4
    );
    // An included default must be literal, as at the top level.
    write(
        d,
        "parts/integrator.xml",
        r#"<scene version="3.0.0"><default name="depth" value="$other"/></scene>"#,
    );
    assert!(error(d, "s.xml").contains("a <default> value must be literal"));
}

#[test]
fn max_depth_defaults_to_mitransients_six_for_both_integrators() {
    // mitransient 1.3.1's integrators take Mitsuba's `ad` default, props.get('max_depth', 6).
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    for kind in ["transient_path", "transient_prbvolpath"] {
        let head = HEAD.replace(
            r#"<integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>"#,
            &format!(r#"<integrator type="{kind}"/>"#),
        );
        write(
            d,
            "s.xml",
            &format!("{}{SHAPES}</scene>", head.replace("SENSOR", FOV)),
        );
        let scene = load(d, "s.xml").unwrap();
        assert_eq!(scene.integrator.max_depth, 6, "{kind}");
        assert_eq!(scene.integrator.rr_depth, 5, "{kind}");
    }
    // Without an <integrator>, Mitsuba's default `path`: unbounded.
    let head = HEAD.replace(
        r#"<integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>"#,
        "",
    );
    write(
        d,
        "s.xml",
        &format!("{}{SHAPES}</scene>", head.replace("SENSOR", FOV)),
    );
    assert_eq!(load(d, "s.xml").unwrap().integrator.max_depth, -1);
}

#[test]
fn a_default_declared_in_an_included_file_is_visible_after_the_include() {
    // mitsuba-data's participating-media tests: include/preamble.xml declares `res`
    // and `spp`, the including scene's film and sampler use them.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    write(
        d,
        "include/preamble.xml",
        r#"<scene version="3.0.0"><default name="res" value="12"/><default name="spp" value="3"/></scene>"#,
    );
    let head = HEAD
        .replace(
            r#"<integer name="width" value="8"/><integer name="height" value="6"/>"#,
            r#"<integer name="width" value="$res"/><integer name="height" value="$res"/>"#,
        )
        .replace(
            r#"<integer name="sample_count" value="4"/>"#,
            r#"<integer name="sample_count" value="$spp"/>"#,
        )
        .replace(
            r#"<scene version="3.0.0">"#,
            r#"<scene version="3.0.0"><include filename="include/preamble.xml"/>"#,
        );
    write(
        d,
        "s.xml",
        &format!("{}{SHAPES}</scene>", head.replace("SENSOR", FOV)),
    );
    let scene = load(d, "s.xml").unwrap();
    assert_eq!(
        (scene.film.width, scene.film.height, scene.spp),
        (12, 12, 3)
    );
    // The scene's own default still wins.
    write(
        d,
        "t.xml",
        &format!("{}{SHAPES}</scene>", head.replace("SENSOR", FOV)).replacen(
            r#"<scene version="3.0.0">"#,
            r#"<scene version="3.0.0"><default name="res" value="10"/>"#,
            1,
        ),
    );
    assert_eq!(load(d, "t.xml").unwrap().film.width, 10);
    // Also when the include is found through a <path> (a copy of the scene elsewhere).
    let elsewhere = tempfile::tempdir().unwrap();
    let copy = format!("{}{SHAPES}</scene>", head.replace("SENSOR", FOV)).replacen(
        r#"<scene version="3.0.0">"#,
        &format!(r#"<scene version="3.0.0"><path value="{}"/>"#, d.display()),
        1,
    );
    write(elsewhere.path(), "s.xml", &copy);
    let scene = load(elsewhere.path(), "s.xml").unwrap();
    assert_eq!((scene.film.width, scene.spp), (12, 3));
}

#[test]
fn a_fan_out_of_includes_is_refused_in_bounded_time() {
    // Each of 12 small files includes the next 8 times: 8^12 inclusions within the depth
    // limit. The total is capped (repeats counted) before any more files are read.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "f12.xml", r#"<scene version="3.0.0"/>"#);
    for k in (0..12).rev() {
        let inc = format!(r#"<include filename="f{}.xml"/>"#, k + 1).repeat(8);
        write(
            d,
            &format!("f{k}.xml"),
            &format!(r#"<scene version="3.0.0">{inc}</scene>"#),
        );
    }
    write(d, "tri.ply", TRI_PLY);
    let text = format!(
        r#"{}<include filename="f0.xml"/>{SHAPES}</scene>"#,
        HEAD.replace("SENSOR", FOV)
    );
    write(d, "s.xml", &text);
    let start = std::time::Instant::now();
    let Err(err) = load(d, "s.xml") else {
        panic!("an include fan-out of 8^12 loaded");
    };
    assert!(err.contains("<include>s in all"), "{err}");
    // Bounded: a few thousand tiny files, not 8^12 (generous for a loaded CI machine).
    assert!(start.elapsed().as_secs() < 30, "{:?}", start.elapsed());
    // A modest fan-out (8 x 8) still loads.
    for k in 0..2 {
        let inc = format!(r#"<include filename="g{}.xml"/>"#, k + 1).repeat(8);
        write(
            d,
            &format!("g{k}.xml"),
            &format!(r#"<scene version="3.0.0">{inc}</scene>"#),
        );
    }
    write(d, "g2.xml", r#"<scene version="3.0.0"/>"#);
    write(d, "t.xml", &text.replace("f0.xml", "g0.xml"));
    assert!(load(d, "t.xml").is_ok());
}

#[test]
fn a_mesh_of_coincident_triangles_builds_its_bvh_in_bounded_time() {
    // 65,536 copies of one triangle: the BVH builder's nearest-neighbour merges all
    // tie, which made the build quadratic (minutes). Now it takes a moment, and the
    // render equals the one of a single copy.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    let ply = |n: usize| {
        let mut s = format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
             property float z\nelement face {n}\nproperty list uchar int vertex_indices\nend_header\n",
            3 * n
        );
        for _ in 0..n {
            s.push_str("-0.5 -0.5 0.5\n0.5 -0.5 0.5\n0 0.5 0.5\n");
        }
        for i in 0..n {
            s.push_str(&format!("3 {} {} {}\n", 3 * i, 3 * i + 1, 3 * i + 2));
        }
        s
    };
    write(d, "one.ply", &ply(1));
    write(d, "many.ply", &ply(65_536));
    let scene = |mesh: &str| {
        format!(
            r#"{}<bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.4"/></bsdf>
  <shape type="rectangle"><ref id="grey"/></shape>
  <shape type="ply"><string name="filename" value="{mesh}"/><ref id="grey"/></shape></scene>"#,
            HEAD.replace("SENSOR", FOV)
        )
    };
    write(d, "one.xml", &scene("one.ply"));
    write(d, "many.xml", &scene("many.ply"));
    let start = std::time::Instant::now();
    let many = load(d, "many.xml").unwrap();
    assert!(start.elapsed().as_secs() < 20, "{:?}", start.elapsed());
    let one = load(d, "one.xml").unwrap();
    let render = |s: &Scene| {
        let settings = tstat::render::RenderSettings {
            spp: 4,
            seed: 3,
            transform: tstat::stats::Transform::Identity,
            pixel_sampling: tstat::render::PixelSampling::Independent,
            replicates: 0,
            pixel_spp: None,
        };
        tstat::render::render(s, &settings, &|_| {}).steady
    };
    assert_eq!(render(&many), render(&one));
}

#[test]
fn a_large_spectrum_file_loads() {
    // Mitsuba reads .spd files of any size; tstat's limit was an undocumented 1 MiB
    // (64 MiB now). 200,000 samples, over 2 MiB, of a flat reflectance 0.5.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    let mut spd = String::from("# flat\n");
    for i in 0..200_000 {
        spd.push_str(&format!("{:.6} 0.5\n", 360.0 + i as f64 * 0.00235));
    }
    assert!(spd.len() > 2 << 20);
    write(d, "flat.spd", &spd);
    write(d, "tri.ply", TRI_PLY);
    let text = format!(
        r#"{}<bsdf type="diffuse" id="grey"><spectrum name="reflectance" filename="flat.spd"/></bsdf>
  <shape type="rectangle"><ref id="grey"/></shape></scene>"#,
        HEAD.replace("SENSOR", FOV)
    );
    write(d, "s.xml", &text);
    assert!(load(d, "s.xml").is_ok());
}

#[test]
fn a_path_naming_a_file_is_accepted_as_mitsuba_does() {
    // Mitsuba checks only that a <path> exists; one naming a file adds nothing useful.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    let text = format!(
        r#"{}<path value="tri.ply"/>{SHAPES}</scene>"#,
        HEAD.replace("SENSOR", FOV)
    );
    write(d, "s.xml", &text);
    assert!(load(d, "s.xml").is_ok());
    // A path that does not exist is still an error.
    write(
        d,
        "t.xml",
        &text.replace(r#"<path value="tri.ply"/>"#, r#"<path value="nothing"/>"#),
    );
    let Err(err) = load(d, "t.xml") else {
        panic!("a <path> to nothing loaded");
    };
    assert!(err.contains("not found"), "{err}");
}

#[test]
fn an_included_file_whose_root_is_one_object_is_that_object() {
    // Mitsuba parses an included file's root element: a <bsdf> root defines that BSDF.
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    write(d, "tri.ply", TRI_PLY);
    write(
        d,
        "red.xml",
        r#"<bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>"#,
    );
    let text = format!(
        r#"{}<include filename="red.xml"/><shape type="rectangle"><ref id="red"/></shape></scene>"#,
        HEAD.replace("SENSOR", FOV)
    );
    write(d, "s.xml", &text);
    let scene = load(d, "s.xml").unwrap();
    assert_eq!(scene.shapes.len(), 1);
    assert_eq!(scene.bsdfs.len(), 1);
}
