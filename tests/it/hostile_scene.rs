//! Hostile scenes and meshes through the real binary: every case must fail with exactly
//! one `error:` line naming the problem, exit 1 (no panic, no abort, no stack overflow),
//! leave nothing at the output path, and finish within a time bound under a 2 GB
//! address-space limit. The cases are a table: adding one is one entry.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Wall-clock bound per case (they take milliseconds; the limit only catches hangs).
const TIME_LIMIT: Duration = Duration::from_secs(20);
/// Address-space limit for the child, in KiB (`ulimit -v`).
const MEMORY_LIMIT_KIB: u64 = 2_000_000;

/// A file the case puts into its temporary directory.
enum File {
    Text(String),
    Bytes(Vec<u8>),
    /// A symbolic link to the given target.
    Link(&'static str),
    Fifo,
    Dir,
    /// A sparse file of this many bytes (nothing is written).
    Sparse(u64),
}

struct Case {
    name: &'static str,
    files: Vec<(&'static str, File)>,
    /// The scene argument: a name inside the case directory, or an absolute path.
    scene: &'static str,
    /// Extra flags after the standard small render flags.
    args: Vec<&'static str>,
    /// Leave out `--width 8 --height 8` (the file's own size is the point).
    own_size: bool,
    /// Leave out `--bins 4`.
    own_bins: bool,
    /// Must appear in the error line.
    want: &'static str,
}

/// A valid scene: 8 x 8 px, 4 bins, an emitting rectangle; `SHAPES` marks where a case
/// adds shapes and `SENSOR` where it adds sensor content.
const BASE: &str = r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
        <film type="transient_hdr_film">
            <integer name="width" value="8"/><integer name="height" value="8"/>
            <integer name="temporal_bins" value="4"/>
            <float name="bin_width_opl" value="1"/>
        </film>
        SENSOR
    </sensor>
    <shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
    SHAPES
</scene>
"#;

fn scene_with(shapes: &str) -> File {
    File::Text(BASE.replace("SHAPES", shapes).replace("SENSOR", ""))
}

fn sensor_with(extra: &str) -> File {
    File::Text(BASE.replace("SHAPES", "").replace("SENSOR", extra))
}

fn base_replace(from: &str, to: &str) -> File {
    let text = BASE.replace("SHAPES", "").replace("SENSOR", "");
    assert!(text.contains(from), "{from}");
    File::Text(text.replace(from, to))
}

fn mesh_scene(kind: &str, file: &str) -> File {
    scene_with(&format!(
        r#"<shape type="{kind}"><string name="filename" value="{file}"/></shape>"#
    ))
}

/// A sphere with `params` in a scene rendered by the volumetric integrator.
fn vol(params: &str) -> File {
    scene_with(&format!(
        r#"<integrator type="transient_prbvolpath"/><shape type="sphere"><bsdf type="null"/>{params}</shape>"#
    ))
}

/// A sphere holding a heterogeneous medium with `params`, rendered by the volumetric
/// integrator.
fn hetero(params: &str) -> File {
    vol(&format!(
        r#"<medium type="heterogeneous" name="interior">{params}</medium>"#
    ))
}

/// A Mitsuba `.vol` file (version 3, float32) of the given size and channels over the
/// unit cube, with `values` as the data (which may be shorter than the header says).
fn vol_bytes(size: [i32; 3], channels: i32, values: &[f32]) -> Vec<u8> {
    let mut b = b"VOL\x03".to_vec();
    for v in [1, size[0], size[1], size[2], channels] {
        b.extend(v.to_le_bytes());
    }
    b.extend(f32s(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]));
    b.extend(f32s(values));
    b
}

/// A heterogeneous medium whose sigma_t is the grid file `g.vol` (absent if `None`).
fn grid_case(name: &'static str, file: Option<File>, want: &'static str) -> Case {
    let scene = hetero(
        r#"<volume name="sigma_t" type="gridvolume"><string name="filename" value="g.vol"/></volume>"#,
    );
    let mut files = vec![("scene.xml", scene)];
    if let Some(f) = file {
        files.push(("g.vol", f));
    }
    case(name, files, want)
}

fn sphere(params: &str) -> File {
    scene_with(&format!(r#"<shape type="sphere">{params}</shape>"#))
}

const PLY_HEADER: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
    property float y\nproperty float z\nelement face 1\n\
    property list uchar int vertex_indices\nend_header\n";

fn ply(body: &str) -> File {
    File::Text(format!("{PLY_HEADER}{body}"))
}

fn binary_ply(header: &str, body: &[u8]) -> File {
    let mut bytes =
        format!("ply\nformat binary_little_endian 1.0\n{header}end_header\n").into_bytes();
    bytes.extend_from_slice(body);
    File::Bytes(bytes)
}

fn f32s(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// A `.serialized` file: the header, then `body` zlib-compressed, then a dictionary of
/// one mesh at offset 0.
fn serialized(version: u16, body: &[u8]) -> File {
    use std::io::Write;
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(body).unwrap();
    let mut f = [0x041Cu16.to_le_bytes(), version.to_le_bytes()].concat();
    f.extend(e.finish().unwrap());
    f.extend(0u64.to_le_bytes());
    f.extend(1u32.to_le_bytes());
    File::Bytes(f)
}

/// A version 4 body: flags (single precision), name, counts, positions, indices.
fn serialized_body(vertices: u64, positions: &[f32], faces: &[u32]) -> Vec<u8> {
    let mut b = 0x1000u32.to_le_bytes().to_vec();
    b.extend(b"m\0");
    b.extend(vertices.to_le_bytes());
    b.extend((faces.len() as u64 / 3).to_le_bytes());
    b.extend(f32s(positions));
    faces.iter().for_each(|i| b.extend(i.to_le_bytes()));
    b
}

const TRIANGLE: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

fn serialized_scene(params: &str) -> File {
    scene_with(&format!(
        r#"<shape type="serialized"><string name="filename" value="m.serialized"/>{params}</shape>"#
    ))
}

/// A `.vol` grid file (Mitsuba's format) with the given header fields and values.
fn vol_file(dims: [i32; 3], channels: i32, values: &[f32]) -> File {
    let mut b = b"VOL\x03".to_vec();
    for v in [1, dims[0], dims[1], dims[2], channels] {
        b.extend(v.to_le_bytes());
    }
    b.extend(f32s(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]));
    b.extend(f32s(values));
    File::Bytes(b)
}

/// A 2 x 2 x 2 grid with one corner inside: one non-empty voxel.
const SDF8: [f32; 8] = [-0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5];

/// An `sdfgrid` reading `g.vol`, with `params`.
fn sdf_case(name: &'static str, vol: File, params: &str, want: &'static str) -> Case {
    case(
        name,
        vec![
            (
                "scene.xml",
                scene_with(&format!(
                    r#"<shape type="sdfgrid"><string name="filename" value="g.vol"/>{params}</shape>"#
                )),
            ),
            ("g.vol", vol),
        ],
        want,
    )
}

fn case(name: &'static str, files: Vec<(&'static str, File)>, want: &'static str) -> Case {
    Case {
        name,
        files,
        scene: "scene.xml",
        args: Vec::new(),
        own_size: false,
        own_bins: false,
        want,
    }
}

fn scene_case(name: &'static str, scene: File, want: &'static str) -> Case {
    case(name, vec![("scene.xml", scene)], want)
}

/// An area light whose radiance is a blackbody whose `<float name="temperature">`
/// takes the attributes `float_attrs`, rendered with `--mode spectral`.
fn blackbody_case(name: &'static str, float_attrs: &str, want: &'static str) -> Case {
    let float_attrs = if float_attrs.starts_with("name=") {
        float_attrs.to_string() + r#" value="5000""#
    } else {
        format!(r#"name="temperature" {float_attrs}"#)
    };
    Case {
        args: vec!["--mode", "spectral"],
        ..scene_case(
            name,
            scene_with(&format!(
                r#"<shape type="sphere"><emitter type="area"><spectrum type="blackbody" name="radiance"><float {float_attrs}/></spectrum></emitter></shape>"#
            )),
            want,
        )
    }
}

fn mesh_case(
    name: &'static str,
    kind: &'static str,
    mesh_name: &'static str,
    mesh: File,
    want: &'static str,
) -> Case {
    case(
        name,
        vec![
            ("scene.xml", mesh_scene(kind, mesh_name)),
            (mesh_name, mesh),
        ],
        want,
    )
}

fn nested(depth: usize, open: &str, inner: &str, close: &str) -> String {
    format!("{}{inner}{}", open.repeat(depth), close.repeat(depth))
}

fn cases() -> Vec<Case> {
    let quad = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    vec![
        // ---- overflow: colours beyond single precision ----
        scene_case(
            "spectrum_reflectance_3e38",
            scene_with(
                r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="400:3e38, 700:3e38"/></bsdf></shape>"#,
            ),
            "beyond single precision",
        ),
        scene_case(
            "uniform_spectrum_radiance_3e38",
            scene_with(
                r#"<shape type="sphere"><emitter type="area"><spectrum name="radiance" value="3e38"/></emitter></shape>"#,
            ),
            "beyond single precision",
        ),
        scene_case(
            "projector_scale_3e38",
            scene_with(&projector(r#"<float name="fov" value="30"/><float name="scale" value="3e38"/>"#)),
            "overflows single precision",
        ),
        // ---- blackbody spectra: bad temperatures, overflow, the wrong mode ----
        blackbody_case("blackbody_temperature_0", r#"value="0""#, "must be positive"),
        blackbody_case("blackbody_temperature_negative", r#"value="-300""#, "must be positive"),
        blackbody_case("blackbody_temperature_nan", r#"value="nan""#, "not a finite number"),
        blackbody_case("blackbody_temperature_inf", r#"value="inf""#, "not a finite number"),
        blackbody_case(
            "blackbody_temperature_1e30",
            r#"value="1e30""#,
            "overflows single precision",
        ),
        blackbody_case(
            "blackbody_temperature_missing",
            r#"name="x""#,
            "needs 'temperature'",
        ),
        Case {
            args: Vec::new(),
            ..blackbody_case(
                "blackbody_in_rgb",
                r#"value="5000""#,
                "renders only with --mode spectral",
            )
        },
        Case {
            args: vec!["--mode", "spectral"],
            ..scene_case(
                "spectral_negative_reflectance_spectrum",
                scene_with(
                    r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="400:-0.1, 700:0.5"/></bsdf></shape>"#,
                ),
                "negative value -0.1",
            )
        },
        Case {
            args: vec!["--mode", "spectral"],
            ..scene_case(
                "spectral_reflectance_3e38",
                scene_with(
                    r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="400:3e38, 700:3e38"/></bsdf></shape>"#,
                ),
                "beyond single precision",
            )
        },
        case(
            "spectrum_file_65_mib",
            vec![
                (
                    "scene.xml",
                    scene_with(r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" filename="big.spd"/></bsdf></shape>"#),
                ),
                ("big.spd", File::Sparse(65 << 20)),
            ],
            "cannot read spectrum file 'big.spd'",
        ),
        case(
            "envmap_16384_squared_png",
            vec![
                ("scene.xml", envmap("big.png", "")),
                ("big.png", png_header(16384, 16384)),
            ],
            "above the limit of 33554432 pixels for an environment map",
        ),
        scene_case(
            "envmap_scale_3e38",
            envmap(SKY, r#"<float name="scale" value="3e38"/>"#),
            "overflows single precision",
        ),
        // ---- scene XML: crashes and runaway memory ----
        scene_case(
            "deep_twosided_100k",
            scene_with(&format!(
                "<shape type=\"cube\">{}</shape>",
                nested(
                    100_000,
                    "<bsdf type=\"twosided\">",
                    "<bsdf type=\"diffuse\"/>",
                    "</bsdf>"
                )
            )),
            "nested more than 64 deep",
        ),
        scene_case(
            "deep_unknown_elements_100k",
            scene_with(&nested(100_000, "<a>", "", "</a>")),
            "nested more than 64 deep",
        ),
        case("scene_is_dev_zero", vec![], "not a regular file").scene_path("/dev/zero"),
        scene_case(
            "scene_links_to_dev_zero",
            File::Link("/dev/zero"),
            "not a regular file",
        ),
        scene_case("scene_is_fifo", File::Fifo, "not a regular file"),
        scene_case("scene_is_directory", File::Dir, "is a directory"),
        scene_case(
            "scene_is_300_mb",
            File::Sparse(300 << 20),
            "above the limit",
        ),
        scene_case(
            "attribute_flood",
            scene_with(&format!(
                "<shape {}/>",
                (0..100_000)
                    .map(|k| format!("a{k}=\"\""))
                    .collect::<Vec<_>>()
                    .join(" ")
            )),
            "an element with 100000 attributes",
        ),
        scene_case(
            "node_flood",
            scene_with(&"<a/>".repeat(4_100_000)),
            "more than 4000000 XML nodes",
        ),
        scene_case(
            "billion_laughs",
            File::Text(format!(
                "<?xml version=\"1.0\"?><!DOCTYPE scene [<!ENTITY a \"aaaaaaaaaa\">{}]><scene>&j;</scene>",
                (b'b'..=b'j')
                    .map(|c| format!(
                        "<!ENTITY {} \"{}\">",
                        c as char,
                        format!("&{};", (c - 1) as char).repeat(10)
                    ))
                    .collect::<String>()
            )),
            "malformed XML",
        ),
        // ---- integrator: time filter and mitransient < 1.0's time window ----
        scene_case(
            "gaussian_stddev_nan",
            scene_with(r#"<integrator type="transient_path"><string name="temporal_filter" value="gaussian"/><float name="gaussian_stddev" value="nan"/></integrator>"#),
            "gaussian_stddev",
        ),
        scene_case(
            "gaussian_stddev_huge",
            scene_with(r#"<integrator type="transient_path"><string name="temporal_filter" value="gaussian"/><float name="gaussian_stddev" value="1e30"/></integrator>"#),
            "at most 64 bins",
        ),
        scene_case(
            "legacy_exposure_zero",
            scene_with(r#"<integrator type="transient_path"><float name="exposure" value="0"/></integrator>"#),
            "exposure (the bin width of mitransient before 1.0) must be positive",
        ),
        scene_case(
            "legacy_initial_time_inf",
            scene_with(r#"<integrator type="transient_path"><float name="initial_time" value="1e39"/></integrator>"#),
            "overflows",
        ),
        // ---- scene XML: numbers ----
        scene_case(
            "radius_1e39",
            sphere(r#"<float name="radius" value="1e39"/>"#),
            r#"<float name="radius">: '1e39' overflows single precision"#,
        ),
        scene_case(
            "ior_1e39",
            sphere(r#"<bsdf type="dielectric"><float name="int_ior" value="1e39"/></bsdf>"#),
            r#"<float name="int_ior">: '1e39' overflows"#,
        ),
        scene_case(
            "ior_ratio_1e8",
            sphere(r#"<bsdf type="dielectric"><float name="int_ior" value="1e4"/><float name="ext_ior" value="1e-4"/></bsdf>"#),
            "relative IOR",
        ),
        scene_case(
            "conductor_k_1e30",
            sphere(r#"<bsdf type="conductor"><rgb name="eta" value="1"/><rgb name="k" value="1e30"/></bsdf>"#),
            "conductor k",
        ),
        // The one bin-width rule (`sensors::film::check_bin_width`), at the element.
        scene_case(
            "bin_width_negative",
            base_replace(r#"name="bin_width_opl" value="1""#, r#"name="bin_width_opl" value="-0.5""#),
            "<float name=\"bin_width_opl\">: bin_width_opl must be positive, got -0.5",
        ),
        scene_case(
            "bin_width_zero",
            base_replace(r#"name="bin_width_opl" value="1""#, r#"name="bin_width_opl" value="0""#),
            "bin_width_opl must be positive, got 0",
        ),
        scene_case(
            "fov_1e39",
            base_replace(r#"value="40""#, r#"value="1e39""#),
            r#"<float name="fov">: '1e39' overflows"#,
        ),
        scene_case(
            "fov_1e-40",
            base_replace(r#"value="40""#, r#"value="1e-40""#),
            "field of view that is zero",
        ),
        scene_case(
            "point_light_position_1e39",
            scene_with(r#"<emitter type="point"><point name="position" x="0" y="1e39" z="0"/></emitter>"#),
            r#"<point name="position">: attribute 'y': '1e39' overflows"#,
        ),
        scene_case(
            "scale_1e39",
            sphere(r#"<transform name="to_world"><scale value="1e39"/></transform>"#),
            "<scale>: attribute 'value': '1e39' overflows",
        ),
        scene_case(
            "radiance_inf",
            scene_with(r#"<shape type="cube"><emitter type="area"><rgb name="radiance" value="inf"/></emitter></shape>"#),
            "'inf' is not a finite number",
        ),
        scene_case(
            "reflectance_nan",
            scene_with(r#"<shape type="cube"><bsdf type="diffuse"><rgb name="reflectance" value="0.5, NaN, 0.5"/></bsdf></shape>"#),
            "'NaN' is not a finite number",
        ),
        scene_case(
            "lookat_nan",
            base_replace("origin=\"0,0,4\"", "origin=\"0,nan,4\""),
            "'nan' is not a finite number",
        ),
        scene_case(
            "translate_1e20_beyond_world",
            scene_with(r#"<shape type="cube"><transform name="to_world"><translate x="1e20"/></transform></shape>"#),
            "lies beyond",
        ),
        scene_case(
            "scales_overflow_f64",
            scene_with(&format!(
                "<shape type=\"cube\"><transform name=\"to_world\">{}</transform></shape>",
                "<scale value=\"1e38\"/>".repeat(10)
            )),
            "the transform overflows",
        ),
        scene_case(
            "cube_edges_of_2e10",
            scene_with(r#"<shape type="cube"><transform name="to_world"><scale value="1e10"/></transform></shape>"#),
            "triangle 0 is too large for single-precision arithmetic",
        ),
        scene_case(
            "scene_spans_3e-5",
            File::Text(
                BASE.replace("SHAPES", "")
                    .replace("SENSOR", "")
                    .replace(
                        r#"<shape type="rectangle">"#,
                        r#"<shape type="rectangle"><transform name="to_world"><scale value="1e-5"/></transform>"#,
                    ),
            ),
            "within ten ray offsets",
        ),
        scene_case(
            "sphere_radius_times_scale_overflows",
            sphere(r#"<float name="radius" value="1e30"/><transform name="to_world"><scale value="1e30"/></transform>"#),
            "world-space radius",
        ),
        // ---- scene XML: transforms ----
        scene_case(
            "projective_matrix",
            sphere(r#"<transform name="to_world"><matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0.5 0 0 1"/></transform>"#),
            "projective transforms are not supported",
        ),
        scene_case(
            "singular_matrix",
            sphere(r#"<transform name="to_world"><matrix value="1 0 0 0 1 0 0 0 0 0 1 0 0 0 0 1"/></transform>"#),
            "singular",
        ),
        scene_case(
            "flat_matrix_1e-200",
            scene_with(r#"<shape type="cube"><transform name="to_world"><matrix value="1 0 0 0 0 1 0 0 0 0 1e-200 0 0 0 0 1"/></transform></shape>"#),
            "singular",
        ),
        scene_case(
            "scale_zero",
            scene_with(r#"<shape type="cube"><transform name="to_world"><scale y="0"/></transform></shape>"#),
            "zero scale",
        ),
        scene_case(
            "emitter_scaled_to_no_area",
            scene_with(r#"<shape type="rectangle"><transform name="to_world"><scale value="1e-30"/></transform><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#),
            "the emitting shape's area is 0",
        ),
        // ---- scene XML: film and sampler ----
        scene_case(
            "width_negative",
            base_replace(r#"name="width" value="8""#, r#"name="width" value="-8""#),
            "width must be positive",
        ),
        scene_case(
            "temporal_bins_zero",
            base_replace(r#"value="4""#, r#"value="0""#),
            "temporal_bins must be positive",
        ),
        scene_case(
            "temporal_bins_1e12_from_the_scene",
            base_replace(r#"value="4""#, r#"value="1000000000000""#),
            "temporal_bins 1000000000000 is above",
        )
        .own_bins(),
        scene_case(
            "film_too_large_to_address",
            base_replace(
                r#"<integer name="width" value="8"/><integer name="height" value="8"/>"#,
                r#"<integer name="width" value="4000000000000"/><integer name="height" value="4000000000000"/>"#,
            ),
            "too large to address",
        )
        .own_size(),
        scene_case(
            "negative_seed",
            sensor_with(r#"<sampler type="independent"><integer name="seed" value="-1"/></sampler>"#),
            "seed must be non-negative",
        ),
        scene_case(
            "two_films",
            sensor_with(r#"<film type="transient_hdr_film"/>"#),
            "a sensor has one <film>",
        ),
        // ---- scene XML: structure ----
        scene_case(
            "not_utf8",
            File::Bytes(b"<scene>\xff\xfe</scene>".to_vec()),
            "not UTF-8",
        ),
        scene_case("empty_file", File::Text(String::new()), "malformed XML"),
        scene_case(
            "unclosed_element",
            File::Text(BASE.replace("</scene>", "")),
            "malformed XML",
        ),
        scene_case(
            "duplicate_id",
            scene_with(r#"<bsdf type="diffuse" id="a"/><shape type="cube" id="a"/>"#),
            "id 'a' is already used on line",
        ),
        // Finding a line number scans the text: only errors may do it, or 300000 ids
        // on one line take minutes.
        scene_case(
            "300k_ids_on_one_line_then_a_duplicate",
            scene_with(
                &((0..300_000)
                    .map(|k| format!("<bsdf type=\"diffuse\" id=\"b{k}\"/>"))
                    .collect::<String>()
                    + "<bsdf type=\"diffuse\" id=\"b0\"/>"),
            ),
            "scene.xml:13: <bsdf type=\"diffuse\">: id 'b0' is already used on line 13",
        ),
        scene_case(
            "duplicate_default",
            base_replace(
                "<scene version=\"3.0.0\">",
                "<scene version=\"3.0.0\"><default name=\"r\" value=\"1\"/><default name=\"r\" value=\"2\"/>",
            ),
            "is given twice",
        ),
        scene_case(
            "self_referencing_default",
            base_replace(
                "<scene version=\"3.0.0\">",
                "<scene version=\"3.0.0\"><default name=\"r\" value=\"$r\"/>",
            ),
            "a <default> value must be literal",
        ),
        scene_case(
            "ref_to_itself",
            scene_with(r#"<bsdf type="twosided" id="a"><ref id="a"/></bsdf>"#),
            "no BSDF with id 'a' defined before this point",
        ),
        scene_case(
            "misspelt_attribute",
            scene_with(r#"<shape type="sphere"><float name="radius" vaule="2"/></shape>"#),
            "unknown attribute 'vaule'",
        ),
        scene_case(
            "two_emitters_on_one_shape",
            scene_with(r#"<shape type="cube"><emitter type="area"><rgb name="radiance" value="1"/></emitter><emitter type="area"><rgb name="radiance" value="2"/></emitter></shape>"#),
            "a shape has at most one emitter",
        ),
        scene_case(
            "define_overflows",
            File::Text(
                BASE.replace("SHAPES", "")
                    .replace("SENSOR", "")
                    .replace(
                        "<scene version=\"3.0.0\">",
                        "<scene version=\"3.0.0\"><default name=\"fov\" value=\"40\"/>",
                    )
                    .replace(r#"<float name="fov" value="40"/>"#, r#"<float name="fov" value="$fov"/>"#),
            ),
            r#"<float name="fov">: '1e39' overflows"#,
        )
        .args(&["-D", "fov=1e39"]),
        scene_case(
            "default_expands_to_100_gb",
            File::Text(
                BASE.replace("SHAPES", "")
                    .replace("SENSOR", "")
                    .replace(
                        "<scene version=\"3.0.0\">",
                        &format!("<scene version=\"3.0.0\"><default name=\"a\" value=\"{}\"/>", "x".repeat(1_000_000)),
                    )
                    .replace("<shape type=\"rectangle\">", &format!("<shape type=\"rectangle\" id=\"{}\">", "$a".repeat(100_000))),
            ),
            "longer than 1048576 bytes",
        ),
        // ---- meshes: file kinds ----
        case(
            "ply_is_dev_zero",
            vec![("scene.xml", mesh_scene("ply", "/dev/zero"))],
            "not a regular file",
        ),
        mesh_case("ply_links_to_dev_zero", "ply", "m.ply", File::Link("/dev/zero"), "not a regular file"),
        mesh_case("obj_links_to_dev_zero", "obj", "m.obj", File::Link("/dev/zero"), "not a regular file"),
        mesh_case("ply_is_fifo", "ply", "m.ply", File::Fifo, "not a regular file"),
        mesh_case("obj_is_fifo", "obj", "m.obj", File::Fifo, "not a regular file"),
        mesh_case("obj_is_directory", "obj", "m.obj", File::Dir, "is a directory"),
        mesh_case("ply_is_17_gib", "ply", "m.ply", File::Sparse(17 << 30), "above the limit"),
        // Within the size limit, beyond the 2 GB address space of the test.
        mesh_case("ply_is_10_gib", "ply", "m.ply", File::Sparse(10 << 30), "more than can be allocated"),
        case(
            "mesh_filename_empty",
            vec![("scene.xml", mesh_scene("obj", ""))],
            "the filename is empty",
        ),
        // ---- PLY contents ----
        mesh_case(
            "ply_ascii_1e12_vertices",
            "ply",
            "m.ply",
            File::Text(PLY_HEADER.replace("vertex 3", "vertex 1000000000000") + quad),
            "declares 1000000000000 entries",
        ),
        mesh_case(
            "ply_binary_4e12_vertices",
            "ply",
            "m.ply",
            binary_ply(
                "element vertex 4000000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n",
                &f32s(&[0.0; 9]),
            ),
            "declares 4000000000000 entries",
        ),
        mesh_case(
            "ply_count_beyond_u64",
            "ply",
            "m.ply",
            File::Text(PLY_HEADER.replace("vertex 3", "vertex 99999999999999999999999") + quad),
            "too large",
        ),
        mesh_case(
            "ply_list_of_4e9_indices",
            "ply",
            "m.ply",
            binary_ply(
                "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uint int vertex_indices\n",
                &[f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]), 4_000_000_000u32.to_le_bytes().to_vec(), vec![0; 12]].concat(),
            ),
            "truncated",
        ),
        mesh_case("ply_index_out_of_range", "ply", "m.ply", ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"), "refers to vertex 7"),
        mesh_case("ply_negative_index", "ply", "m.ply", ply("0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n"), "refers to vertex -1"),
        mesh_case("ply_coordinate_1e39", "ply", "m.ply", ply("0 0 0\n1e39 0 0\n0 1 0\n3 0 1 2\n"), "is not finite"),
        mesh_case(
            "ply_binary_nan",
            "ply",
            "m.ply",
            binary_ply(
                "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n",
                &[f32s(&[0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0, 1.0, 0.0]), vec![3], vec![0; 12]].concat(),
            ),
            "vertex 1: position",
        ),
        mesh_case("ply_too_few_lines", "ply", "m.ply", File::Text(PLY_HEADER.replace("vertex 3", "vertex 100") + &"0 0 0\n".repeat(20)), "declares 100 entries but only"),
        mesh_case("ply_truncated", "ply", "m.ply", ply("0 0 0\n1 0 0\n"), "truncated"),
        mesh_case("ply_without_faces", "ply", "m.ply", File::Text(PLY_HEADER.replace("face 1", "face 0") + "0 0 0\n1 0 0\n0 1 0\n"), "has no faces"),
        mesh_case("ply_not_ply", "ply", "m.ply", File::Text("solid cube\nendsolid\n".into()), "not a PLY file"),
        mesh_case("ply_far_vertex", "ply", "m.ply", ply("0 0 0\n1e20 0 0\n0 1 0\n3 0 1 2\n"), "lies beyond"),
        // ---- serialized contents ----
        mesh_case("serialized_links_to_dev_zero", "serialized", "m.serialized", File::Link("/dev/zero"), "not a regular file"),
        mesh_case("serialized_is_17_gib", "serialized", "m.serialized", File::Sparse(17 << 30), "above the limit"),
        // Read in place: a large file is not loaded whole (its zero header is refused).
        mesh_case("serialized_is_10_gib", "serialized", "m.serialized", File::Sparse(10 << 30), "not a serialized mesh"),
        mesh_case("serialized_not_serialized", "serialized", "m.serialized", ply("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"), "not a serialized mesh"),
        mesh_case("serialized_truncated_header", "serialized", "m.serialized", File::Bytes(vec![0x1C, 0x04, 4]), "truncated header"),
        mesh_case("serialized_version_9", "serialized", "m.serialized", File::Bytes(vec![0x1C, 0x04, 9, 0, 0x78, 0x9C]), "unsupported version 9"),
        mesh_case("serialized_not_zlib", "serialized", "m.serialized", File::Bytes([vec![0x1C, 0x04, 4, 0], vec![0xAB; 64]].concat()), "corrupt compressed data"),
        mesh_case("serialized_empty_stream", "serialized", "m.serialized", File::Bytes(vec![0x1C, 0x04, 4, 0]), "end early"),
        mesh_case(
            "serialized_4e9_vertices",
            "serialized",
            "m.serialized",
            serialized(4, &serialized_body(4_000_000_000, &TRIANGLE, &[0, 1, 2])),
            "compressed bytes left",
        ),
        mesh_case(
            "serialized_vertices_beyond_u32",
            "serialized",
            "m.serialized",
            serialized(4, &serialized_body(1 << 40, &TRIANGLE, &[0, 1, 2])),
            "more than 4294967295",
        ),
        // Counts within what the stream could hold (data that do not compress well), the
        // data shorter.
        mesh_case(
            "serialized_zeros_short_of_the_counts",
            "serialized",
            "m.serialized",
            serialized(4, &serialized_body(300_000, &(0..870_000).map(|i| (i % 1009) as f32 * 0.37).collect::<Vec<_>>(), &[0, 1, 2])),
            "end early",
        ),
        mesh_case(
            "serialized_counts_below_the_data",
            "serialized",
            "m.serialized",
            serialized(4, &[serialized_body(3, &TRIANGLE, &[0, 1, 2]), vec![0; 12]].concat()),
            "more data than its counts",
        ),
        mesh_case(
            "serialized_index_out_of_range",
            "serialized",
            "m.serialized",
            serialized(4, &serialized_body(3, &TRIANGLE, &[0, 1, 3])),
            "triangle 0 refers to vertex 3",
        ),
        mesh_case(
            "serialized_nan",
            "serialized",
            "m.serialized",
            serialized(4, &serialized_body(3, &[0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0, 1.0, 0.0], &[0, 1, 2])),
            "vertex 1: position",
        ),
        mesh_case(
            "serialized_far_vertex",
            "serialized",
            "m.serialized",
            serialized(4, &serialized_body(3, &[0.0, 0.0, 0.0, 1e20, 0.0, 0.0, 0.0, 1.0, 0.0], &[0, 1, 2])),
            "lies beyond",
        ),
        mesh_case(
            "serialized_without_faces",
            "serialized",
            "m.serialized",
            serialized(4, &serialized_body(3, &TRIANGLE, &[])),
            "has no faces",
        ),
        case(
            "serialized_shape_index_out_of_range",
            vec![
                ("scene.xml", serialized_scene(r#"<integer name="shape_index" value="1"/>"#)),
                ("m.serialized", serialized(4, &serialized_body(3, &TRIANGLE, &[0, 1, 2]))),
            ],
            "shape_index 1 is out of range: the file holds 1 mesh",
        ),
        case(
            "serialized_shape_index_negative",
            vec![
                ("scene.xml", serialized_scene(r#"<integer name="shape_index" value="-1"/>"#)),
                ("m.serialized", serialized(4, &serialized_body(3, &TRIANGLE, &[0, 1, 2]))),
            ],
            "shape_index must be non-negative",
        ),
        // ---- OBJ contents ----
        mesh_case("obj_empty", "obj", "m.obj", File::Text(String::new()), "has no faces"),
        mesh_case("obj_index_out_of_range", "obj", "m.obj", File::Text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n".into()), "vertex index 4 is out of range"),
        mesh_case("obj_index_beyond_i64", "obj", "m.obj", File::Text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n".into()), "malformed face vertex"),
        mesh_case("obj_nan", "obj", "m.obj", File::Text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n".into()), "is not finite"),
        mesh_case("obj_two_corner_face", "obj", "m.obj", File::Text("v 0 0 0\nv 1 0 0\nf 1 2\n".into()), "at least 3 are needed"),
        mesh_case("obj_not_utf8", "obj", "m.obj", File::Bytes(b"v 0 0 0\xff\n".to_vec()), "not valid UTF-8"),
        case(
            "obj_emitter_without_area",
            vec![
                (
                    "scene.xml",
                    scene_with(r#"<shape type="obj"><string name="filename" value="m.obj"/><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#),
                ),
                ("m.obj", File::Text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n".into())),
            ],
            "the emitting shape's area is 0",
        ),
        // Materials added with the BSDF interface: every bad parameter names itself.
        scene_case(
            "unknown_microfacet_distribution",
            sphere(r#"<bsdf type="roughconductor"><string name="distribution" value="phong"/></bsdf>"#),
            "unknown microfacet distribution 'phong'",
        ),
        scene_case(
            "roughness_out_of_range",
            sphere(r#"<bsdf type="roughconductor"><float name="alpha" value="0"/></bsdf>"#),
            "roughness 0 is outside [1e-4, 10]",
        ),
        scene_case(
            "alpha_u_without_alpha_v",
            sphere(r#"<bsdf type="roughconductor"><float name="alpha_u" value="0.1"/></bsdf>"#),
            "'alpha_u' and 'alpha_v' must be given together",
        ),
        scene_case(
            "alpha_and_alpha_u",
            sphere(r#"<bsdf type="roughconductor"><float name="alpha" value="0.1"/><float name="alpha_u" value="0.3"/></bsdf>"#),
            "give either 'alpha' or 'alpha_u' and 'alpha_v'",
        ),
        scene_case(
            "unknown_conductor_material",
            sphere(r#"<bsdf type="conductor"><string name="material" value="Unobtainium"/></bsdf>"#),
            "unknown conductor material 'Unobtainium'",
        ),
        scene_case(
            "material_and_eta",
            sphere(r#"<bsdf type="roughconductor"><string name="material" value="Au"/><rgb name="eta" value="1"/></bsdf>"#),
            "give either 'material' or 'eta' and 'k', not both",
        ),
        scene_case(
            "roughdielectric_without_an_interface",
            sphere(r#"<bsdf type="roughdielectric"><float name="int_ior" value="1.2"/><float name="ext_ior" value="1.2"/></bsdf>"#),
            "roughdielectric needs int_ior and ext_ior to differ",
        ),
        scene_case(
            "roughdielectric_negative_transmittance",
            sphere(r#"<bsdf type="roughdielectric"><rgb name="specular_transmittance" value="0.5, -0.1, 0.5"/></bsdf>"#),
            "specular_transmittance must be non-negative",
        ),
        scene_case(
            "roughdielectric_alpha_v_out_of_range",
            sphere(r#"<bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha_u" value="0.2"/><float name="alpha_v" value="20"/></bsdf>"#),
            "roughness 20 is outside [1e-4, 10]",
        ),
        scene_case(
            "roughdielectric_roughness_out_of_range",
            sphere(r#"<bsdf type="roughdielectric"><float name="alpha" value="-0.2"/></bsdf>"#),
            "roughness -0.2 is outside [1e-4, 10]",
        ),
        scene_case(
            "roughdielectric_unknown_ior",
            sphere(r#"<bsdf type="roughdielectric"><string name="int_ior" value="kryptonite"/></bsdf>"#),
            "unknown IOR name 'kryptonite'",
        ),
        scene_case(
            "twosided_roughdielectric",
            sphere(r#"<bsdf type="twosided"><bsdf type="roughdielectric"/></bsdf>"#),
            "not a dielectric, roughdielectric",
        ),
        scene_case(
            "plastic_reflects_nothing",
            sphere(r#"<bsdf type="plastic"><rgb name="diffuse_reflectance" value="0"/><rgb name="specular_reflectance" value="0"/></bsdf>"#),
            "plastic with zero diffuse and specular reflectance",
        ),
        scene_case(
            "medium_with_transient_path",
            sphere(r#"<bsdf type="null"/><medium type="homogeneous" name="interior"/>"#),
            "use <integrator type=\"transient_prbvolpath\">",
        ),
        scene_case(
            "medium_negative_sigma_t",
            vol(r#"<medium type="homogeneous" name="interior"><float name="sigma_t" value="-1"/></medium>"#),
            "sigma_t must be finite and >= 0",
        ),
        scene_case(
            "medium_albedo_above_one",
            vol(r#"<medium type="homogeneous" name="interior"><rgb name="albedo" value="0.5, 1.2, 0.5"/></medium>"#),
            "albedo must lie in [0, 1]",
        ),
        scene_case(
            "medium_nan_scale",
            vol(r#"<medium type="homogeneous" name="interior"><float name="scale" value="nan"/></medium>"#),
            "scale",
        ),
        scene_case(
            "medium_negative_scale",
            vol(r#"<medium type="homogeneous" name="interior"><float name="scale" value="-2"/></medium>"#),
            "scale must be finite and >= 0",
        ),
        scene_case(
            "medium_sigma_a_alone",
            vol(r#"<medium type="homogeneous" name="interior"><float name="sigma_a" value="1"/></medium>"#),
            "sigma_a needs sigma_s",
        ),
        scene_case(
            "medium_both_parametrisations",
            vol(r#"<medium type="homogeneous" name="interior"><float name="sigma_a" value="1"/><float name="sigma_s" value="1"/><float name="sigma_t" value="1"/></medium>"#),
            "not both",
        ),
        scene_case(
            "medium_huge_extinction",
            vol(r#"<medium type="homogeneous" name="interior"><float name="sigma_t" value="1e30"/></medium>"#),
            "above 1e7",
        ),
        scene_case(
            "medium_unknown_type",
            vol(r#"<medium type="rayleigh_fog" name="interior"/>"#),
            "medium 'rayleigh_fog' is not supported",
        ),
        grid_case("vol_missing_file", None, "volume 'g.vol'"),
        grid_case(
            "vol_truncated",
            Some(File::Bytes(vol_bytes([2, 2, 2], 1, &[1.0; 8])[..70].to_vec())),
            "volume 'g.vol' is truncated",
        ),
        grid_case(
            "vol_huge_dims",
            Some(File::Bytes(vol_bytes([100_000, 100_000, 100_000], 3, &[1.0; 8]))),
            "is truncated: a 100000 x 100000 x 100000 grid of 3 channel(s) needs",
        ),
        grid_case(
            "vol_short_header",
            Some(File::Bytes(b"VOL\x03\x01\x00".to_vec())),
            "shorter than the 48-byte header",
        ),
        grid_case(
            "vol_bad_magic",
            Some(File::Bytes([b"XOL".as_slice(), &vol_bytes([1, 1, 1], 1, &[1.0])[3..]].concat())),
            "does not start with 'VOL'",
        ),
        grid_case(
            "vol_six_channels",
            Some(File::Bytes(vol_bytes([1, 1, 1], 6, &[1.0; 6]))),
            "has 6 channels",
        ),
        grid_case(
            "vol_nan",
            Some(File::Bytes(vol_bytes([2, 1, 1], 1, &[1.0, f32::NAN]))),
            "non-finite value NaN at voxel (x 1, y 0, z 0)",
        ),
        grid_case(
            "vol_negative_sigma_t",
            Some(File::Bytes(vol_bytes([2, 1, 1], 1, &[1.0, -0.5]))),
            "as sigma_t they must be >= 0",
        ),
        grid_case("vol_is_fifo", Some(File::Fifo), "not a regular file"),
        grid_case("vol_is_directory", Some(File::Dir), "is a directory"),
        grid_case(
            "vol_sparse_huge",
            Some(File::Sparse(8 << 30)),
            "above the limit",
        ),
        case(
            "vol_albedo_above_one",
            vec![
                ("scene.xml", hetero(r#"<volume name="albedo" type="gridvolume"><string name="filename" value="g.vol"/></volume>"#)),
                ("g.vol", File::Bytes(vol_bytes([1, 1, 1], 3, &[0.5, 1.5, 0.5]))),
            ],
            "as albedo they must be [0, 1]",
        ),
        case(
            "vol_max_value_below_grid",
            vec![
                ("scene.xml", hetero(r#"<volume name="sigma_t" type="gridvolume"><string name="filename" value="g.vol"/><float name="max_value" value="1"/></volume>"#)),
                ("g.vol", File::Bytes(vol_bytes([2, 1, 1], 1, &[1.0, 3.0]))),
            ],
            "max_value 1 is below the grid's largest value 3",
        ),
        case(
            "vol_grid_bbox_empty",
            vec![
                ("scene.xml", hetero(r#"<volume name="sigma_t" type="gridvolume"><string name="filename" value="g.vol"/><boolean name="use_grid_bbox" value="true"/></volume>"#)),
                ("g.vol", File::Bytes({
                    let mut b = vol_bytes([1, 1, 1], 1, &[1.0]);
                    b[36..40].copy_from_slice(&0f32.to_le_bytes());
                    b
                })),
            ],
            "which is empty",
        ),
        case(
            "homogeneous_grid_sigma_t",
            vec![
                ("scene.xml", vol(r#"<medium type="homogeneous" name="interior"><volume name="sigma_t" type="gridvolume"><string name="filename" value="g.vol"/></volume></medium>"#)),
                ("g.vol", File::Bytes(vol_bytes([1, 1, 1], 1, &[1.0]))),
            ],
            "a homogeneous medium's sigma_t must be constant",
        ),
        scene_case(
            "gridvolume_without_filename",
            hetero(r#"<volume name="sigma_t" type="gridvolume"/>"#),
            "missing parameter 'filename'",
        ),
        scene_case(
            "gridvolume_bad_filter",
            hetero(r#"<volume name="sigma_t" type="gridvolume"><string name="filter_type" value="cubic"/><string name="filename" value="g.vol"/></volume>"#),
            "filter_type 'cubic' is not one of: trilinear, nearest",
        ),
        scene_case(
            "gridvolume_bad_wrap",
            hetero(r#"<volume name="sigma_t" type="gridvolume"><string name="wrap_mode" value="border"/><string name="filename" value="g.vol"/></volume>"#),
            "wrap_mode 'border' is not one of: clamp, repeat, mirror",
        ),
        scene_case(
            "constvolume_negative",
            hetero(r#"<volume name="sigma_t" type="constvolume"><rgb name="value" value="1, -1, 1"/></volume>"#),
            "the sigma_t volume's value must be finite and >= 0",
        ),
        scene_case(
            "constvolume_albedo_above_one",
            hetero(r#"<volume name="albedo" type="constvolume"><float name="value" value="1.5"/></volume>"#),
            "the albedo volume's value must be finite and [0, 1]",
        ),
        scene_case(
            "volume_singular_to_world",
            hetero(r#"<volume name="sigma_t" type="constvolume"><transform name="to_world"><matrix value="1 0 0 0 0 0 0 0 0 0 1 0 0 0 0 1"/></transform></volume>"#),
            "singular",
        ),
        scene_case(
            "volume_unknown_type",
            hetero(r#"<volume name="sigma_t" type="openvdb"/>"#),
            "volume 'openvdb' is not supported (supported: constvolume, gridvolume)",
        ),
        scene_case(
            "volume_unknown_slot",
            hetero(r#"<volume name="density" type="constvolume"/>"#),
            "unexpected <volume name=\"density\">",
        ),
        scene_case(
            "volume_given_twice",
            hetero(r#"<float name="sigma_t" value="1"/><volume name="sigma_t" type="constvolume"/>"#),
            "'sigma_t' is given twice",
        ),
        scene_case(
            "heterogeneous_huge_majorant",
            hetero(r#"<float name="scale" value="1e30"/>"#),
            "is above 1e7",
        ),
        scene_case(
            "heterogeneous_negative_sigma_t",
            hetero(r#"<rgb name="sigma_t" value="1, -2, 1"/>"#),
            "sigma_t must be finite and >= 0",
        ),
        scene_case(
            "heterogeneous_sigma_a",
            hetero(r#"<float name="sigma_a" value="1"/>"#),
            "unknown parameter 'sigma_a'",
        ),
        scene_case(
            "medium_without_slot_name",
            vol(r#"<medium type="homogeneous"/>"#),
            "needs name=\"interior\" or name=\"exterior\"",
        ),
        scene_case(
            "medium_twice_interior",
            vol(r#"<medium type="homogeneous" name="interior"/><medium type="homogeneous" name="interior"/>"#),
            "a shape has one interior medium",
        ),
        scene_case(
            "medium_unknown_parameter",
            vol(r#"<medium type="homogeneous" name="interior"><float name="density" value="1"/></medium>"#),
            "unknown parameter 'density'",
        ),
        scene_case(
            "phase_g_one",
            vol(r#"<medium type="homogeneous" name="interior"><phase type="hg"><float name="g" value="1"/></phase></medium>"#),
            "g must lie in (-1, 1)",
        ),
        scene_case(
            "phase_g_nan",
            vol(r#"<medium type="homogeneous" name="interior"><phase type="hg"><float name="g" value="nan"/></phase></medium>"#),
            "g",
        ),
        scene_case(
            "phase_unknown",
            vol(r#"<medium type="homogeneous" name="interior"><phase type="rayleigh"/></medium>"#),
            "phase function 'rayleigh' is not supported",
        ),
        scene_case(
            "phase_twice",
            vol(r#"<medium type="homogeneous" name="interior"><phase type="isotropic"/><phase type="isotropic"/></medium>"#),
            "only a single phase function",
        ),
        scene_case(
            "medium_ref_missing",
            vol(r#"<ref name="interior" id="nowhere"/>"#),
            "'nowhere'",
        ),
        scene_case(
            "top_level_medium_without_id",
            File::Text(BASE.replace("SHAPES", r#"<medium type="homogeneous"/>"#).replace("SENSOR", "")),
            "a top-level <medium> needs an id",
        ),
        scene_case(
            "sensor_two_media",
            File::Text(BASE.replace("SHAPES", "<integrator type=\"transient_prbvolpath\"/>").replace("SENSOR", r#"<medium type="homogeneous"/><medium type="homogeneous"/>"#)),
            "a sensor has at most one medium",
        ),
        scene_case(
            "mask_in_volumetric_scene",
            scene_with(r#"<integrator type="transient_prbvolpath"/><shape type="sphere"><bsdf type="mask"><bsdf type="diffuse"/></bsdf></shape>"#),
            "bsdf 'mask' is not supported by transient_prbvolpath",
        ),
        scene_case(
            "twosided_null",
            sphere(r#"<bsdf type="twosided"><bsdf type="null"/></bsdf>"#),
            "twosided wraps only one-sided models (diffuse, conductor, roughconductor, plastic, roughplastic, pplastic); not a dielectric, roughdielectric, thindielectric, null, mask",
        ),
        scene_case(
            "texture_on_a_parameter_that_takes_none",
            sphere(r#"<bsdf type="dielectric"><texture type="checkerboard" name="int_ior"/></bsdf>"#),
            "unexpected nested element in <bsdf type=\"dielectric\">",
        ),
        scene_case(
            "separable_without_a_profile",
            sphere(r#"<bsdf type="Separable"><bsdf type="diffuse"/></bsdf>"#),
            "Separable needs a nested BSDF and a <TemporalProfile",
        ),
        scene_case(
            "separable_without_a_bsdf",
            sphere(r#"<bsdf type="Separable"><TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="1"/></TemporalProfile></bsdf>"#),
            "Separable needs a nested BSDF and a <TemporalProfile",
        ),
        scene_case(
            "unknown_temporal_profile",
            sphere(r#"<bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="GammaTP" name="tp"/></bsdf>"#),
            "unknown temporal profile 'GammaTP'",
        ),
        scene_case(
            "constant_profile_without_delay",
            sphere(r#"<bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ConstantTP" name="tp"/></bsdf>"#),
            "ConstantTP needs 'delay'",
        ),
        scene_case(
            "negative_delay",
            sphere(r#"<bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="-1"/></TemporalProfile></bsdf>"#),
            "delay must be >= 0",
        ),
        scene_case(
            "zero_lambda",
            sphere(r#"<bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ExponentialTP" name="tp"><float name="lambda" value="0"/></TemporalProfile></bsdf>"#),
            "lambda must be > 0",
        ),
        scene_case(
            "epanechnikov_mu_below_sigma",
            sphere(r#"<bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="EpanechnikovTP" name="tp"><float name="mu" value="0.1"/><float name="sigma" value="0.5"/></TemporalProfile></bsdf>"#),
            "mu must be >= sigma",
        ),
        scene_case(
            "profile_with_a_typo",
            sphere(r#"<bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ExponentialTP" name="tp"><float name="lamda" value="1"/><float name="lambda" value="1"/></TemporalProfile></bsdf>"#),
            "lamda",
        ),
        scene_case(
            "separable_in_separable",
            sphere(r#"<bsdf type="Separable"><bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="1"/></TemporalProfile></bsdf><TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="1"/></TemporalProfile></bsdf>"#),
            "Separable cannot nest another delaying BSDF",
        ),
        scene_case(
            "composed_with_one_child",
            sphere(r#"<bsdf type="Composed"><float name="weight" value="0.5"/><bsdf type="diffuse"/></bsdf>"#),
            "Composed needs exactly two nested BSDFs",
        ),
        scene_case(
            "composed_weight_out_of_range",
            sphere(r#"<bsdf type="Composed"><float name="weight" value="1.5"/><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#),
            "weight must be in [0, 1]",
        ),
        scene_case(
            "mask_around_a_delay",
            sphere(r#"<bsdf type="mask"><bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="1"/></TemporalProfile></bsdf></bsdf>"#),
            "mask cannot wrap a delaying BSDF",
        ),
        scene_case(
            "twosided_around_a_delay",
            sphere(r#"<bsdf type="twosided"><bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="1"/></TemporalProfile></bsdf></bsdf>"#),
            "Separable(twosided(...))",
        ),
        scene_case(
            "mask_without_a_nested_bsdf",
            sphere(r#"<bsdf type="mask"><float name="opacity" value="0.5"/></bsdf>"#),
            "mask needs exactly one nested BSDF",
        ),
        // ---- blendbsdf, normalmap, bumpmap, pplastic, polarizer ----
        scene_case(
            "blendbsdf_without_weight",
            sphere(r#"<bsdf type="blendbsdf"><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#),
            "blendbsdf needs 'weight'",
        ),
        scene_case(
            "blendbsdf_with_one_bsdf",
            sphere(r#"<bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/></bsdf>"#),
            "blendbsdf needs exactly two nested BSDFs",
        ),
        scene_case(
            "blendbsdf_nan_weight",
            sphere(r#"<bsdf type="blendbsdf"><float name="weight" value="nan"/><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#),
            "'nan' is not a finite number",
        ),
        scene_case(
            "blendbsdf_around_a_delay",
            sphere(r#"<bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/><bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="1"/></TemporalProfile></bsdf></bsdf>"#),
            "blendbsdf cannot blend a delaying BSDF",
        ),
        scene_case(
            "blendbsdf_two_rough_glasses",
            sphere(r#"<bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="roughdielectric"/><bsdf type="roughdielectric"><float name="int_ior" value="2"/></bsdf></bsdf>"#),
            "cannot blend two rough dielectrics of different IORs",
        ),
        scene_case(
            "normalmap_without_a_texture",
            sphere(r#"<bsdf type="normalmap"><bsdf type="diffuse"/></bsdf>"#),
            "normalmap needs a texture 'normalmap'",
        ),
        scene_case(
            "normalmap_missing_file",
            sphere(r#"<bsdf type="normalmap"><texture type="bitmap" name="normalmap"><string name="filename" value="nowhere.png"/></texture><bsdf type="diffuse"/></bsdf>"#),
            "nowhere.png",
        ),
        scene_case(
            "normalmap_without_a_bsdf",
            sphere(r#"<bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/></bsdf>"#),
            "normalmap needs exactly one nested BSDF",
        ),
        scene_case(
            "normalmap_negative_flag",
            sphere(r#"<bsdf type="normalmap"><boolean name="flip_invalid_normals" value="maybe"/><texture type="checkerboard" name="normalmap"/><bsdf type="diffuse"/></bsdf>"#),
            "flip_invalid_normals",
        ),
        scene_case(
            "twosided_normalmap",
            sphere(r#"<bsdf type="twosided"><bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/><bsdf type="diffuse"/></bsdf></bsdf>"#),
            "twosided wraps only one-sided models",
        ),
        scene_case(
            "bumpmap_without_a_texture",
            sphere(r#"<bsdf type="bumpmap"><float name="scale" value="0.1"/><bsdf type="diffuse"/></bsdf>"#),
            "bumpmap needs one nested <texture>",
        ),
        scene_case(
            "bumpmap_two_textures",
            sphere(r#"<bsdf type="bumpmap"><texture type="checkerboard" name="a"/><texture type="checkerboard" name="b"/><bsdf type="diffuse"/></bsdf>"#),
            "bumpmap takes exactly one nested texture",
        ),
        scene_case(
            "bumpmap_nan_scale",
            sphere(r#"<bsdf type="bumpmap"><float name="scale" value="NaN"/><texture type="checkerboard" name="h"/><bsdf type="diffuse"/></bsdf>"#),
            "'NaN' is not a finite number",
        ),
        scene_case(
            "bumpmap_missing_file",
            sphere(r#"<bsdf type="bumpmap"><texture type="bitmap" name="h"><string name="filename" value="gone.png"/></texture><bsdf type="diffuse"/></bsdf>"#),
            "gone.png",
        ),
        scene_case(
            "bumpmap_around_a_normalmap",
            sphere(r#"<bsdf type="bumpmap"><texture type="checkerboard" name="h"/><bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/><bsdf type="diffuse"/></bsdf></bsdf>"#),
            "bumpmap cannot wrap another normalmap or bumpmap",
        ),
        scene_case(
            "bumpmap_around_a_delay",
            sphere(r#"<bsdf type="bumpmap"><texture type="checkerboard" name="h"/><bsdf type="Separable"><bsdf type="diffuse"/><TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="1"/></TemporalProfile></bsdf></bsdf>"#),
            "bumpmap cannot wrap a delaying BSDF",
        ),
        scene_case(
            "pplastic_equal_iors",
            sphere(r#"<bsdf type="pplastic"><float name="int_ior" value="1.3"/><float name="ext_ior" value="1.3"/></bsdf>"#),
            "pplastic's int_ior and ext_ior must differ",
        ),
        scene_case(
            "pplastic_eta_and_int_ior",
            sphere(r#"<bsdf type="pplastic"><float name="eta" value="1.3"/><float name="int_ior" value="1.5"/></bsdf>"#),
            "give either 'eta' or 'int_ior' and 'ext_ior'",
        ),
        scene_case(
            "pplastic_negative_eta",
            sphere(r#"<bsdf type="pplastic"><float name="eta" value="-1.3"/></bsdf>"#),
            "eta must be positive",
        ),
        scene_case(
            "pplastic_negative_diffuse",
            sphere(r#"<bsdf type="pplastic"><rgb name="diffuse_reflectance" value="0.5, -0.1, 0.2"/></bsdf>"#),
            "diffuse_reflectance must be non-negative",
        ),
        scene_case(
            "pplastic_negative_alpha",
            sphere(r#"<bsdf type="pplastic"><float name="alpha" value="-0.2"/></bsdf>"#),
            "roughness -0.2 is outside [1e-4, 10]",
        ),
        scene_case(
            "pplastic_reflects_nothing",
            sphere(r#"<bsdf type="pplastic"><rgb name="diffuse_reflectance" value="0"/><rgb name="specular_reflectance" value="0"/></bsdf>"#),
            "pplastic with zero diffuse and specular reflectance",
        ),
        // ---- principled, principledthin ----
        scene_case(
            "principled_metallic_above_one",
            sphere(r#"<bsdf type="principled"><float name="metallic" value="1.5"/></bsdf>"#),
            "metallic must be in [0, 1], got 1.5",
        ),
        scene_case(
            "principled_negative_roughness",
            sphere(r#"<bsdf type="principled"><float name="roughness" value="-0.1"/></bsdf>"#),
            "roughness must be in [0, 1], got -0.1",
        ),
        scene_case(
            "principled_nan_clearcoat",
            sphere(r#"<bsdf type="principled"><float name="clearcoat" value="nan"/></bsdf>"#),
            "clearcoat",
        ),
        scene_case(
            "principled_eta_and_specular",
            sphere(r#"<bsdf type="principled"><float name="eta" value="1.3"/><float name="specular" value="0.4"/></bsdf>"#),
            "give either 'eta' or 'specular', not both",
        ),
        scene_case(
            "principled_zero_eta",
            sphere(r#"<bsdf type="principled"><float name="eta" value="0"/></bsdf>"#),
            "eta must be positive",
        ),
        scene_case(
            "principled_negative_specular",
            sphere(r#"<bsdf type="principled"><float name="specular" value="-0.5"/></bsdf>"#),
            "specular must be in [0, 12.5)",
        ),
        scene_case(
            "principled_specular_beyond_its_mapping",
            sphere(r#"<bsdf type="principled"><float name="specular" value="13"/></bsdf>"#),
            "specular must be in [0, 12.5)",
        ),
        scene_case(
            "principled_negative_base_color",
            sphere(r#"<bsdf type="principled"><rgb name="base_color" value="0.5, -0.1, 0.2"/></bsdf>"#),
            "base_color must be non-negative",
        ),
        scene_case(
            "principled_negative_sampling_rate",
            sphere(r#"<bsdf type="principled"><float name="clearcoat_sampling_rate" value="-1"/></bsdf>"#),
            "clearcoat_sampling_rate must be non-negative",
        ),
        scene_case(
            "principled_missing_texture_file",
            sphere(r#"<bsdf type="principled"><texture type="bitmap" name="base_color"><string name="filename" value="nowhere.png"/></texture></bsdf>"#),
            "nowhere.png",
        ),
        scene_case(
            "principled_has_no_sample_visible",
            sphere(r#"<bsdf type="principled"><boolean name="sample_visible" value="false"/></bsdf>"#),
            "unknown parameter 'sample_visible'",
        ),
        scene_case(
            "principled_textured_eta",
            sphere(r#"<bsdf type="principled"><texture type="checkerboard" name="eta"/></bsdf>"#),
            "unexpected nested element",
        ),
        scene_case(
            "principledthin_diff_trans_above_two",
            sphere(r#"<bsdf type="principledthin"><float name="diff_trans" value="2.5"/></bsdf>"#),
            "diff_trans must be in [0, 2], got 2.5",
        ),
        scene_case(
            "principledthin_negative_eta",
            sphere(r#"<bsdf type="principledthin"><float name="eta" value="-1.5"/></bsdf>"#),
            "eta must be positive",
        ),
        scene_case(
            "principledthin_has_no_clearcoat",
            sphere(r#"<bsdf type="principledthin"><float name="clearcoat" value="0.5"/></bsdf>"#),
            "unknown parameter 'clearcoat'",
        ),
        scene_case(
            "polarizer_negative_transmittance",
            sphere(r#"<bsdf type="polarizer"><rgb name="transmittance" value="-0.5"/></bsdf>"#),
            "transmittance must be non-negative",
        ),
        scene_case(
            "polarizer_unknown_parameter",
            sphere(r#"<bsdf type="polarizer"><float name="angle" value="30"/></bsdf>"#),
            "angle",
        ),
        scene_case(
            "retarder_negative_transmittance",
            sphere(r#"<bsdf type="retarder"><rgb name="transmittance" value="-0.5"/></bsdf>"#),
            "transmittance must be non-negative",
        ),
        scene_case(
            "retarder_unknown_parameter",
            sphere(r#"<bsdf type="retarder"><float name="phase" value="30"/></bsdf>"#),
            "phase",
        ),
        scene_case(
            "circular_unknown_parameter",
            sphere(r#"<bsdf type="circular"><float name="theta" value="30"/></bsdf>"#),
            "theta",
        ),
        scene_case(
            "circular_bad_handedness",
            sphere(r#"<bsdf type="circular"><string name="left_handed" value="maybe"/></bsdf>"#),
            "left_handed",
        ),
        scene_case(
            "mask_with_two_nested_bsdfs",
            sphere(r#"<bsdf type="mask"><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#),
            "mask needs exactly one nested BSDF",
        ),
        scene_case(
            "twosided_around_a_mask",
            sphere(r#"<bsdf type="twosided"><bsdf type="mask"><bsdf type="diffuse"/></bsdf></bsdf>"#),
            "write mask(twosided(...))",
        ),
        scene_case(
            "textured_alpha_v_without_alpha_u",
            sphere(r#"<bsdf type="roughconductor"><texture type="checkerboard" name="alpha_v"/></bsdf>"#),
            "'alpha_u' and 'alpha_v' must be given together",
        ),
        scene_case(
            "texture_reference_to_nothing",
            sphere(r#"<bsdf type="roughconductor"><ref name="alpha" id="missing"/></bsdf>"#),
            "no <texture id=\"missing\">",
        ),
        // roughplastic: Mitsuba's has `alpha` only, and needs a coating that exists.
        scene_case(
            "roughplastic_alpha_u",
            sphere(r#"<bsdf type="roughplastic"><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.1"/></bsdf>"#),
            "roughplastic has no 'alpha_u': its roughness is isotropic, give 'alpha'",
        ),
        scene_case(
            "roughplastic_equal_iors",
            sphere(r#"<bsdf type="roughplastic"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1.5"/></bsdf>"#),
            "roughplastic's int_ior and ext_ior must differ",
        ),
        scene_case(
            "roughplastic_negative_alpha",
            sphere(r#"<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="-0.25"/></bsdf>"#),
            "roughness -0.25 is outside [1e-4, 10]",
        ),
        scene_case(
            "roughplastic_reflects_nothing",
            sphere(r#"<bsdf type="roughplastic"><rgb name="diffuse_reflectance" value="0"/><float name="specular_reflectance" value="0"/></bsdf>"#),
            "roughplastic with zero diffuse and specular reflectance",
        ),
        scene_case(
            "roughplastic_negative_reflectance",
            sphere(r#"<bsdf type="roughplastic"><rgb name="diffuse_reflectance" value="0.5, -0.1, 0.5"/></bsdf>"#),
            "diffuse_reflectance must be non-negative",
        ),
        scene_case(
            "roughplastic_textured_alpha",
            sphere(r#"<bsdf type="roughplastic"><texture type="checkerboard" name="alpha"/></bsdf>"#),
            "roughplastic's alpha must be a number, not a texture",
        ),
        scene_case(
            "roughplastic_unknown_ior_name",
            sphere(r#"<bsdf type="roughplastic"><string name="int_ior" value="kryptonite"/></bsdf>"#),
            "unknown IOR name 'kryptonite'",
        ),
        // mesh_attribute, rawconstant, textured emitters
        scene_case(
            "mesh_attribute_without_name",
            scene_with(r#"<shape type="sphere"><bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"/></bsdf></shape>"#),
            "missing parameter 'name'",
        ),
        scene_case(
            "mesh_attribute_bad_name",
            scene_with(r#"<shape type="sphere"><bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"><string name="name" value="color"/></texture></bsdf></shape>"#),
            "invalid mesh attribute name 'color'",
        ),
        scene_case(
            "mesh_attribute_absent_from_shape",
            scene_with(r#"<shape type="sphere"><bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"><string name="name" value="vertex_color"/></texture></bsdf></shape>"#),
            "reads 'vertex_color', which this shape does not have (its attributes: none",
        ),
        case(
            "mesh_attribute_absent_from_ply",
            vec![
                ("scene.xml", File::Text(BASE.replace("SENSOR", "").replace("SHAPES", r#"<shape type="ply"><string name="filename" value="m.ply"/><bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"><string name="name" value="face_colour"/></texture></bsdf></shape>"#))),
                ("m.ply", File::Text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nproperty float color_0\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 0.5\n".into())),
            ],
            "reads 'face_colour', which this shape does not have (its attributes: face_color;",
        ),
        case(
            "ply_attribute_twice",
            vec![
                ("scene.xml", mesh_scene("ply", "m.ply")),
                ("m.ply", File::Text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float r\nproperty float g\nproperty float b\nproperty float color_0\nproperty float color_1\nproperty float color_2\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 1 1 1 1 1 1\n1 0 0 1 1 1 1 1 1\n0 1 0 1 1 1 1 1 1\n3 0 1 2\n".into())),
            ],
            "mesh attribute 'vertex_color' is defined twice",
        ),
        scene_case(
            "mesh_attribute_as_area_radiance",
            scene_with(r#"<shape type="sphere"><emitter type="area"><texture type="mesh_attribute" name="radiance"><string name="name" value="vertex_color"/></texture></emitter></shape>"#),
            "a mesh_attribute texture cannot be an area light's radiance",
        ),
        scene_case(
            "mesh_attribute_in_checkerboard",
            scene_with(r#"<shape type="sphere"><bsdf type="diffuse"><texture type="checkerboard" name="reflectance"><texture type="mesh_attribute" name="color0"><string name="name" value="vertex_color"/></texture></texture></bsdf></shape>"#),
            "a mesh_attribute texture cannot be a checkerboard's colour",
        ),
        scene_case(
            "rawconstant_without_value",
            scene_with(r#"<shape type="sphere"><bsdf type="diffuse"><texture type="rawconstant" name="reflectance"/></bsdf></shape>"#),
            "missing parameter 'value'",
        ),
        scene_case(
            "area_radiance_texture_negative",
            scene_with(r#"<shape type="rectangle"><emitter type="area"><texture type="checkerboard" name="radiance"><float name="color0" value="-1"/></texture></emitter></shape>"#),
            "radiance must be finite and non-negative everywhere",
        ),
        scene_case(
            "area_radiance_texture_missing_file",
            scene_with(r#"<shape type="rectangle"><emitter type="area"><texture type="bitmap" name="radiance"><string name="filename" value="nowhere.png"/></texture></emitter></shape>"#),
            "image 'nowhere.png'",
        ),
        scene_case(
            "spot_texture_constant",
            scene_with(r#"<emitter type="spot"><texture type="rawconstant" name="texture"><float name="value" value="1"/></texture></emitter>"#),
            "a spot's 'texture' must vary over uv",
        ),
        scene_case(
            "spot_texture_negative",
            scene_with(r#"<emitter type="spot"><texture type="checkerboard" name="texture"><float name="color1" value="-2"/></texture></emitter>"#),
            "the spot's texture must be finite and non-negative everywhere",
        ),
        scene_case(
            "spot_texture_missing_file",
            scene_with(r#"<emitter type="spot"><texture type="bitmap" name="texture"><string name="filename" value="none.jpg"/></texture></emitter>"#),
            "image 'none.jpg'",
        ),
        // projector (Mitsuba 3's)
        scene_case(
            "projector_fov_180",
            scene_with(&projector(r#"<float name="fov" value="180"/>"#)),
            "fov must be in (0, 180) degrees, got 180",
        ),
        scene_case(
            "projector_fov_negative",
            scene_with(&projector(r#"<float name="fov" value="-30"/>"#)),
            "fov must be in (0, 180) degrees, got -30",
        ),
        scene_case(
            "projector_fov_nan",
            scene_with(&projector(r#"<float name="fov" value="nan"/>"#)),
            "<float name=\"fov\">",
        ),
        scene_case(
            "projector_fov_and_focal_length",
            scene_with(&projector(r#"<float name="fov" value="30"/><string name="focal_length" value="35mm"/>"#)),
            "give either 'fov' or 'focal_length', not both",
        ),
        scene_case(
            "projector_bad_fov_axis",
            scene_with(&projector(r#"<float name="fov" value="30"/><string name="fov_axis" value="z"/>"#)),
            "fov_axis 'z' is not one of",
        ),
        scene_case(
            "projector_missing_texture_file",
            scene_with(&projector(r#"<float name="fov" value="30"/><texture type="bitmap" name="irradiance"><string name="filename" value="nowhere.png"/></texture>"#)),
            "image 'nowhere.png'",
        ),
        scene_case(
            "projector_texture_reference_to_nothing",
            scene_with(&projector(r#"<float name="fov" value="30"/><ref name="irradiance" id="missing"/>"#)),
            "no <texture id=\"missing\">",
        ),
        scene_case(
            "projector_negative_irradiance",
            scene_with(&projector(r#"<float name="fov" value="30"/><rgb name="irradiance" value="1, -1, 1"/>"#)),
            "irradiance must be finite and non-negative",
        ),
        scene_case(
            "projector_negative_scale",
            scene_with(&projector(r#"<float name="fov" value="30"/><float name="scale" value="-2"/>"#)),
            "scale must be finite and non-negative, got -2",
        ),
        scene_case(
            "projector_unknown_parameter",
            scene_with(&projector(r#"<float name="fov" value="30"/><rgb name="intensity" value="1"/>"#)),
            "unknown parameter 'intensity'",
        ),
        scene_case(
            "projector_on_a_shape",
            scene_with(r#"<shape type="sphere"><emitter type="projector"><float name="fov" value="30"/></emitter></shape>"#),
            "emitter 'projector' cannot be attached to a shape",
        ),
        // angulararea (mitransient's)
        scene_case(
            "angulararea_negative_cutoff",
            scene_with(&angular(r#"<float name="cutoff_angle" value="-10"/>"#)),
            "cutoff_angle must be in (0, 180] degrees, got -10",
        ),
        scene_case(
            "angulararea_zero_cutoff",
            scene_with(&angular(r#"<float name="cutoff_angle" value="0"/>"#)),
            "cutoff_angle must be in (0, 180] degrees, got 0",
        ),
        scene_case(
            "angulararea_cutoff_beyond_180",
            scene_with(&angular(r#"<float name="cutoff_angle" value="200"/>"#)),
            "cutoff_angle must be in (0, 180] degrees, got 200",
        ),
        scene_case(
            "angulararea_cutoff_nan",
            scene_with(&angular(r#"<float name="cutoff_angle" value="nan"/>"#)),
            "<float name=\"cutoff_angle\">",
        ),
        scene_case(
            "angulararea_beam_wider_than_cutoff",
            scene_with(&angular(r#"<float name="cutoff_angle" value="20"/><float name="beam_width" value="30"/>"#)),
            "beam_width must be in [0, cutoff_angle = 20] degrees, got 30",
        ),
        scene_case(
            "angulararea_negative_beam",
            scene_with(&angular(r#"<float name="beam_width" value="-1"/>"#)),
            "beam_width must be in [0, cutoff_angle = 10] degrees, got -1",
        ),
        scene_case(
            "angulararea_negative_radiance",
            scene_with(&angular(r#"<rgb name="radiance" value="-1"/>"#)),
            "radiance must be non-negative",
        ),
        scene_case(
            "angulararea_textured_radiance",
            scene_with(&angular(r#"<texture type="checkerboard" name="radiance"/>"#)),
            "a textured radiance is not supported",
        ),
        scene_case(
            "angulararea_top_level_without_id",
            scene_with(r#"<emitter type="angulararea"/>"#),
            "a top-level area emitter needs an id",
        ),
        // ---- sensors: thinlens, orthographic ----
        scene_case(
            "thinlens_missing_aperture",
            sensor_kind("thinlens", r#"<float name="fov" value="40"/>"#),
            "missing parameter 'aperture_radius'",
        ),
        scene_case(
            "thinlens_negative_aperture",
            sensor_kind("thinlens", r#"<float name="fov" value="40"/><float name="aperture_radius" value="-0.1"/>"#),
            "aperture_radius must be in [0",
        ),
        scene_case(
            "thinlens_nan_aperture",
            sensor_kind("thinlens", r#"<float name="fov" value="40"/><float name="aperture_radius" value="nan"/>"#),
            "aperture_radius",
        ),
        scene_case(
            "thinlens_zero_focus",
            sensor_kind("thinlens", r#"<float name="fov" value="40"/><float name="aperture_radius" value="0.1"/><float name="focus_distance" value="0"/>"#),
            "focus_distance must be in (0",
        ),
        scene_case(
            "thinlens_infinite_focus",
            sensor_kind("thinlens", r#"<float name="fov" value="40"/><float name="aperture_radius" value="0.1"/><float name="focus_distance" value="inf"/>"#),
            "focus_distance",
        ),
        scene_case(
            "thinlens_scaled_to_world",
            sensor_kind_to_world("thinlens", r#"<float name="fov" value="40"/><float name="aperture_radius" value="0.1"/>"#, r#"<scale value="2"/>"#),
            "scale factors in the camera's to_world are not allowed",
        ),
        scene_case(
            "thinlens_bad_fov",
            sensor_kind("thinlens", r#"<float name="fov" value="180"/><float name="aperture_radius" value="0.1"/>"#),
            "fov must be in (0, 180)",
        ),
        scene_case(
            "orthographic_with_fov",
            sensor_kind("orthographic", r#"<float name="fov" value="40"/>"#),
            "fov",
        ),
        scene_case(
            "orthographic_flat_to_world",
            sensor_kind_to_world("orthographic", "", r#"<matrix value="1 1 0 0 1 1 0 0 0 0 1 0 0 0 0 1"/>"#),
            "singular",
        ),
        scene_case(
            "orthographic_huge_to_world",
            sensor_kind_to_world("orthographic", "", r#"<scale value="1e30"/>"#),
            "orthographic: to_world's axes",
        ),
        scene_case(
            "sensor_negative_near_clip",
            sensor_kind("orthographic", r#"<float name="near_clip" value="-1"/>"#),
            "near_clip must be in (0, 1e15]",
        ),
        scene_case(
            "sensor_far_clip_below_near",
            sensor_kind("thinlens", r#"<float name="fov" value="40"/><float name="aperture_radius" value="0.1"/><float name="near_clip" value="2"/><float name="far_clip" value="1"/>"#),
            "far_clip must be finite and greater than near_clip",
        ),
        // ---- disk, cylinder ----
        scene_case(
            "disk_flat_to_world",
            scene_with(r#"<shape type="disk"><transform name="to_world"><matrix value="1 1 0 0 1 1 0 0 0 0 1 0 0 0 0 1"/></transform></shape>"#),
            "singular",
        ),
        scene_case(
            "disk_huge_to_world",
            scene_with(r#"<shape type="disk"><transform name="to_world"><scale value="1e30"/></transform></shape>"#),
            "to_world",
        ),
        scene_case(
            "disk_radius_parameter",
            scene_with(r#"<shape type="disk"><float name="radius" value="2"/></shape>"#),
            "radius",
        ),
        scene_case(
            "cylinder_negative_radius",
            scene_with(r#"<shape type="cylinder"><float name="radius" value="-1"/></shape>"#),
            "cylinder radius must be positive",
        ),
        scene_case(
            "cylinder_nan_radius",
            scene_with(r#"<shape type="cylinder"><float name="radius" value="nan"/></shape>"#),
            "radius",
        ),
        scene_case(
            "cylinder_zero_length",
            scene_with(r#"<shape type="cylinder"><point name="p0" x="1" y="1" z="1"/><point name="p1" x="1" y="1" z="1"/></shape>"#),
            "must differ",
        ),
        scene_case(
            "cylinder_nonuniform_scale",
            scene_with(r#"<shape type="cylinder"><transform name="to_world"><scale x="1" y="3" z="1"/></transform></shape>"#),
            "cross-section uniformly",
        ),
        scene_case(
            "cylinder_huge",
            scene_with(r#"<shape type="cylinder"><float name="radius" value="1e20"/></shape>"#),
            "cylinder",
        ),
        // ---- sdfgrid ----
        scene_case("sdfgrid_without_filename", scene_with(r#"<shape type="sdfgrid"/>"#), "\"filename\" parameter"),
        scene_case(
            "sdfgrid_missing_file",
            scene_with(r#"<shape type="sdfgrid"><string name="filename" value="absent.vol"/></shape>"#),
            "absent.vol",
        ),
        sdf_case("sdfgrid_empty_file", File::Bytes(Vec::new()), "", "shorter than the 48-byte header"),
        sdf_case("sdfgrid_is_17_gib", File::Sparse(17 << 30), "", "above the limit"),
        sdf_case("sdfgrid_header_only", vol_file([2, 2, 2], 1, &[]), "", "truncated"),
        sdf_case("sdfgrid_truncated", vol_file([4, 4, 4], 1, &[0.5; 10]), "", "needs 304 bytes, the file has 88"),
        sdf_case("sdfgrid_huge_dims", vol_file([i32::MAX; 3], 1, &SDF8), "", "truncated"),
        sdf_case("sdfgrid_zero_dims", vol_file([0, 2, 2], 1, &[]), "", "every size must be positive"),
        sdf_case("sdfgrid_negative_dims", vol_file([2, -2, 2], 1, &SDF8), "", "every size must be positive"),
        sdf_case("sdfgrid_one_value_wide", vol_file([1, 2, 2], 1, &SDF8[..4]), "", "at least 2 along each axis"),
        sdf_case("sdfgrid_three_channels", vol_file([2, 2, 2], 3, &[0.5; 24]), "", "has 3 channels, expected 1"),
        sdf_case("sdfgrid_nan_value", vol_file([2, 2, 2], 1, &[-0.5, 0.5, f32::NAN, 0.5, 0.5, 0.5, 0.5, 0.5]), "", "non-finite value NaN at voxel (x 0, y 1, z 0)"),
        sdf_case("sdfgrid_infinite_value", vol_file([2, 2, 2], 1, &[-0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, f32::INFINITY]), "", "non-finite value inf"),
        sdf_case("sdfgrid_no_zero_crossing", vol_file([2, 2, 2], 1, &[0.5; 8]), "", "no zero crossing"),
        sdf_case("sdfgrid_bad_normals", vol_file([2, 2, 2], 1, &SDF8), r#"<string name="normals" value="falloff"/>"#, "invalid normals mode \"falloff\""),
        // Mitsuba: 'unreferenced property "flip_normals"' (its sdfgrid reads none).
        sdf_case("sdfgrid_flip_normals", vol_file([2, 2, 2], 1, &SDF8), r#"<boolean name="flip_normals" value="true"/>"#, "unknown parameter 'flip_normals'"),
        sdf_case("sdfgrid_emitter", vol_file([2, 2, 2], 1, &SDF8), r#"<emitter type="area"/>"#, "an sdfgrid cannot be an emitter"),
        sdf_case(
            "sdfgrid_singular_to_world",
            vol_file([2, 2, 2], 1, &SDF8),
            r#"<transform name="to_world"><scale x="1" y="0" z="1"/></transform>"#,
            "singular",
        ),
        sdf_case(
            "sdfgrid_huge_to_world",
            vol_file([2, 2, 2], 1, &SDF8),
            r#"<transform name="to_world"><scale value="1e30"/></transform>"#,
            "beyond",
        ),
        // Mitsuba 3.9.1: 'Plugin "Rectangle" not found' (plugin names are case-sensitive).
        // ---- curves: linearcurve, bsplinecurve ----
        scene_case(
            "curve_file_missing",
            scene_with(r#"<shape type="linearcurve"><string name="filename" value="none.txt"/></shape>"#),
            "linearcurve file 'none.txt'",
        ),
        scene_case(
            "curve_no_filename",
            scene_with(r#"<shape type="bsplinecurve"/>"#),
            "missing parameter 'filename'",
        ),
        case(
            "curve_non_numeric",
            vec![
                ("scene.xml", scene_with(r#"<shape type="linearcurve"><string name="filename" value="c.txt"/></shape>"#)),
                ("c.txt", File::Text("0 0 0 0.1\n1 x 0 0.1\n".into())),
            ],
            "line 2: 'x' is not a number",
        ),
        case(
            "curve_negative_radius",
            vec![
                ("scene.xml", scene_with(r#"<shape type="linearcurve"><string name="filename" value="c.txt"/></shape>"#)),
                ("c.txt", File::Text("0 0 0 0.1\n1 0 0 -0.1\n".into())),
            ],
            "radius -0.1 must be finite and non-negative",
        ),
        case(
            "curve_nan_position",
            vec![
                ("scene.xml", scene_with(r#"<shape type="linearcurve"><string name="filename" value="c.txt"/></shape>"#)),
                ("c.txt", File::Text("0 nan 0 0.1\n1 0 0 0.1\n".into())),
            ],
            "not finite",
        ),
        case(
            "bspline_too_few_points",
            vec![
                ("scene.xml", scene_with(r#"<shape type="bsplinecurve"><string name="filename" value="c.txt"/></shape>"#)),
                ("c.txt", File::Text("0 0 0 0.1\n1 0 0 0.1\n2 0 0 0.1\n".into())),
            ],
            "needs at least 4 per curve",
        ),
        case(
            "curve_empty_file",
            vec![
                ("scene.xml", scene_with(r#"<shape type="linearcurve"><string name="filename" value="c.txt"/></shape>"#)),
                ("c.txt", File::Text("\n\n".into())),
            ],
            "no control points",
        ),
        case(
            "curve_file_is_a_directory",
            vec![
                ("scene.xml", scene_with(r#"<shape type="linearcurve"><string name="filename" value="c.txt"/></shape>"#)),
                ("c.txt", File::Dir),
            ],
            "c.txt",
        ),
        case(
            "curve_area_emitter",
            vec![
                ("scene.xml", scene_with(r#"<shape type="linearcurve"><string name="filename" value="c.txt"/><emitter type="area"/></shape>"#)),
                ("c.txt", File::Text("0 0 0 0.1\n1 0 0 0.1\n".into())),
            ],
            "cannot be an area emitter",
        ),
        case(
            "curve_flip_normals",
            vec![
                ("scene.xml", scene_with(r#"<shape type="linearcurve"><string name="filename" value="c.txt"/><boolean name="flip_normals" value="true"/></shape>"#)),
                ("c.txt", File::Text("0 0 0 0.1\n1 0 0 0.1\n".into())),
            ],
            "flip_normals",
        ),
        // Mitsuba 3.9.1: 'Plugin "Rectangle" not found' (plugin names are case-sensitive).
        // ---- shapegroup, instance ----
        scene_case(
            "shapegroup_without_id",
            scene_with(r#"<shape type="shapegroup"><shape type="sphere"/></shape>"#),
            "a shapegroup needs an id",
        ),
        scene_case(
            "shapegroup_with_emitter",
            scene_with(r#"<shape type="shapegroup" id="g"><shape type="sphere"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape></shape>"#),
            "instancing of emitters is not supported",
        ),
        scene_case(
            "shapegroup_nested",
            scene_with(r#"<shape type="shapegroup" id="g"><shape type="shapegroup" id="h"/></shape>"#),
            "nested instancing",
        ),
        scene_case(
            "instance_without_ref",
            scene_with(r#"<shape type="instance"/>"#),
            "a reference to a 'shapegroup' must be specified",
        ),
        scene_case(
            "instance_of_unknown_group",
            scene_with(r#"<shape type="instance"><ref id="nope"/></shape>"#),
            "'nope' is not a shapegroup declared before this instance",
        ),
        scene_case(
            "instance_before_its_group",
            scene_with(r#"<shape type="instance"><ref id="g"/></shape><shape type="shapegroup" id="g"><shape type="sphere"/></shape>"#),
            "'g' is not a shapegroup declared before",
        ),
        scene_case(
            "instance_two_groups",
            scene_with(r#"<shape type="shapegroup" id="g"><shape type="sphere"/></shape><shape type="instance"><ref id="g"/><ref id="g"/></shape>"#),
            "only a single shapegroup",
        ),
        scene_case(
            "instance_nonuniform_sphere",
            scene_with(r#"<shape type="shapegroup" id="g"><shape type="sphere"/></shape><shape type="instance"><ref id="g"/><transform name="to_world"><scale x="2"/></transform></shape>"#),
            "an instance of a sphere must scale uniformly",
        ),
        scene_case(
            "instance_huge",
            scene_with(r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape><shape type="instance"><ref id="g"/><transform name="to_world"><scale value="1e30"/></transform></shape>"#),
            "shapegroup 'g'",
        ),
        scene_case(
            "sensor_unknown_type",
            sensor_kind("fisheye", ""),
            "sensor 'fisheye' is not supported",
        ),
        // ---- infinitely distant emitters ----
        scene_case("envmap_without_filename", scene_with(r#"<emitter type="envmap"/>"#), "missing parameter 'filename'"),
        scene_case("envmap_missing_file", envmap("none.exr", ""), "image 'none.exr'"),
        case(
            "envmap_not_an_image",
            vec![("scene.xml", envmap("e.exr", "")), ("e.exr", File::Text("not an image".into()))],
            "image 'e.exr' is not a PNG, JPEG, BMP, Radiance HDR or OpenEXR image",
        ),
        case(
            "envmap_zero_size",
            vec![
                ("scene.xml", envmap("e.hdr", "")),
                ("e.hdr", File::Text("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 0 +X 4\n".into())),
            ],
            "image 'e.hdr'",
        ),
        case(
            "envmap_nan_texel",
            vec![
                ("scene.xml", envmap("e.exr", "")),
                ("e.exr", exr(4, 3, |x, y| if (x, y) == (2, 1) { [1.0, f32::NAN, 1.0] } else { [1.0; 3] })),
            ],
            "image 'e.exr' has a non-finite value (NaN)",
        ),
        case(
            "envmap_infinite_texel",
            vec![
                ("scene.xml", envmap("e.exr", "")),
                ("e.exr", exr(4, 3, |x, _| if x == 3 { [f32::INFINITY; 3] } else { [1.0; 3] })),
            ],
            "image 'e.exr' has a non-finite value (inf)",
        ),
        scene_case("envmap_negative_scale", envmap(SKY, r#"<float name="scale" value="-1"/>"#), "scale must be non-negative"),
        scene_case("envmap_nan_scale", envmap(SKY, r#"<float name="scale" value="nan"/>"#), "scale"),
        scene_case(
            "envmap_scaled_to_world",
            envmap(SKY, r#"<transform name="to_world"><scale value="2"/></transform>"#),
            "to_world must be a rotation",
        ),
        scene_case(
            "envmap_filter_type",
            envmap(SKY, r#"<string name="filter_type" value="nearest"/>"#),
            "envmap has no parameter 'filter_type' in Mitsuba 3",
        ),
        scene_case("envmap_unknown_parameter", envmap(SKY, r#"<float name="gamma" value="2"/>"#), "gamma"),
        scene_case(
            "two_environment_emitters",
            scene_with(r#"<emitter type="constant"/><emitter type="constant"/>"#),
            "at most one environment emitter",
        ),
        scene_case(
            "envmap_and_constant",
            envmap_and(SKY, "", r#"<emitter type="constant"/>"#),
            "at most one environment emitter",
        ),
        scene_case(
            "constant_negative_radiance",
            scene_with(r#"<emitter type="constant"><rgb name="radiance" value="1, -1, 1"/></emitter>"#),
            "radiance must be non-negative",
        ),
        scene_case(
            "constant_textured_radiance",
            scene_with(r#"<emitter type="constant"><texture type="checkerboard" name="radiance"/></emitter>"#),
            "unexpected nested element in <emitter type=\"constant\">",
        ),
        scene_case(
            "directional_zero_direction",
            scene_with(r#"<emitter type="directional"><vector name="direction" value="0, 0, 0"/></emitter>"#),
            "direction is zero",
        ),
        scene_case(
            "directional_direction_and_to_world",
            scene_with(r#"<emitter type="directional"><vector name="direction" value="0, 0, 1"/><transform name="to_world"><rotate x="1" angle="30"/></transform></emitter>"#),
            "either 'direction' or 'to_world'",
        ),
        scene_case(
            "directional_negative_irradiance",
            scene_with(r#"<emitter type="directional"><rgb name="irradiance" value="-2"/></emitter>"#),
            "irradiance must be non-negative",
        ),
        scene_case(
            "directional_on_a_shape",
            scene_with(r#"<shape type="cube"><emitter type="directional"/></shape>"#),
            "cannot be attached to a shape",
        ),
    ]
}

/// A top-level projector with `params`.
fn projector(params: &str) -> String {
    format!(r#"<emitter type="projector">{params}</emitter>"#)
}

/// A sphere with an `angulararea` emitter with `params`.
fn angular(params: &str) -> String {
    format!(r#"<shape type="sphere"><emitter type="angulararea">{params}</emitter></shape>"#)
}
/// The base scene with a sensor of `kind` whose fov line is replaced by `params`.
fn sensor_kind(kind: &str, params: &str) -> File {
    let text = BASE.replace("SHAPES", "").replace("SENSOR", "");
    File::Text(
        text.replace(
            r#"<sensor type="perspective">"#,
            &format!(r#"<sensor type="{kind}">"#),
        )
        .replace(r#"<float name="fov" value="40"/>"#, params),
    )
}

/// As `sensor_kind`, with `extra` transform elements before the look-at.
fn sensor_kind_to_world(kind: &str, params: &str, extra: &str) -> File {
    let File::Text(text) = sensor_kind(kind, params) else {
        unreachable!()
    };
    File::Text(text.replace(
        r#"<transform name="to_world"><lookat"#,
        &format!(r#"<transform name="to_world">{extra}<lookat"#),
    ))
}

/// The bundled environment image, by absolute path.
const SKY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/textures/sky.exr");

/// The base scene with an envmap of `file` with extra `params`.
fn envmap(file: &str, params: &str) -> File {
    envmap_and(file, params, "")
}

/// As [`envmap`], then `more` at the top level.
fn envmap_and(file: &str, params: &str, more: &str) -> File {
    scene_with(&format!(
        r#"<emitter type="envmap"><string name="filename" value="{file}"/>{params}</emitter>{more}"#
    ))
}

/// The first bytes of a PNG of `w x h` RGB8 texels: signature and a valid IHDR, no
/// image data (enough for the header check, which must refuse it before decoding).
fn png_header(w: u32, h: u32) -> File {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = 0xFFFF_FFFFu32;
        for &b in bytes {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 2, 0, 0, 0]);
    let mut b = b"\x89PNG\r\n\x1a\n".to_vec();
    b.extend(13u32.to_be_bytes());
    b.extend(&ihdr);
    b.extend(crc32(&ihdr).to_be_bytes());
    // An IDAT chunk (its data a stub): readers stop the header there.
    let idat = b"IDAT\x78\x9c\x03\x00\x00\x00\x00\x01".to_vec();
    b.extend(((idat.len() - 4) as u32).to_be_bytes());
    b.extend(&idat);
    b.extend(crc32(&idat).to_be_bytes());
    File::Bytes(b)
}

/// An RGB f32 OpenEXR image of `w x h` texels.
fn exr(w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3] + Sync) -> File {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("i.exr");
    exr::prelude::write_rgb_file(&path, w, h, |x, y| {
        let [r, g, b] = f(x, y);
        (r, g, b)
    })
    .unwrap();
    File::Bytes(std::fs::read(&path).unwrap())
}

impl Case {
    fn scene_path(mut self, path: &'static str) -> Self {
        self.scene = path;
        self
    }
    fn own_bins(mut self) -> Self {
        self.own_bins = true;
        self
    }
    fn own_size(mut self) -> Self {
        self.own_size = true;
        self
    }
    fn args(mut self, args: &[&'static str]) -> Self {
        self.args.extend_from_slice(args);
        self
    }
}

fn make(dir: &Path, name: &str, file: &File) {
    let path = dir.join(name);
    match file {
        File::Text(t) => std::fs::write(&path, t).unwrap(),
        File::Bytes(b) => std::fs::write(&path, b).unwrap(),
        File::Link(target) => std::os::unix::fs::symlink(target, &path).unwrap(),
        File::Fifo => {
            let ok = Command::new("mkfifo").arg(&path).status().unwrap();
            assert!(ok.success(), "mkfifo failed");
        }
        File::Dir => std::fs::create_dir(&path).unwrap(),
        File::Sparse(n) => std::fs::File::create(&path).unwrap().set_len(*n).unwrap(),
    }
}

struct Outcome {
    code: Option<i32>,
    stderr: String,
    timed_out: bool,
}

/// Runs the binary under the memory limit, killing it after [`TIME_LIMIT`].
/// `TSTAT_BIN` runs another build instead (e.g. an older one, to see the corpus catch
/// what it fixed).
fn run(dir: &Path, args: &[String]) -> Outcome {
    let err_path = dir.join(".stderr");
    let out_path = dir.join(".stdout");
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {MEMORY_LIMIT_KIB} && exec \"$0\" \"$@\""
        ))
        .arg(std::env::var("TSTAT_BIN").unwrap_or(env!("CARGO_BIN_EXE_tstat").into()))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_path).unwrap())
        .stderr(std::fs::File::create(&err_path).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let mut timed_out = false;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > TIME_LIMIT {
            child.kill().unwrap();
            child.wait().unwrap();
            timed_out = true;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = String::from_utf8_lossy(&std::fs::read(&err_path).unwrap()).into_owned();
    std::fs::remove_file(&err_path).unwrap();
    std::fs::remove_file(&out_path).unwrap();
    Outcome {
        code: status.code(),
        stderr,
        timed_out,
    }
}

fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

fn render_args(c: &Case, dir: &Path, out: &Path) -> Vec<String> {
    let scene = if c.scene.starts_with('/') {
        PathBuf::from(c.scene)
    } else {
        dir.join(c.scene)
    };
    let mut args: Vec<String> = vec![
        "render".into(),
        scene.display().to_string(),
        "--out".into(),
        out.display().to_string(),
        "--spp".into(),
        "2".into(),
    ];
    if !c.own_size {
        args.extend(["--width", "8", "--height", "8"].map(String::from));
    }
    if !c.own_bins {
        args.extend(["--bins", "4"].map(String::from));
    }
    args.extend(c.args.iter().map(|a| a.to_string()));
    args
}

/// Checks one case; returns a description of what went wrong, if anything.
fn check(c: &Case) -> Result<(), String> {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for (name, file) in &c.files {
        make(dir, name, file);
    }
    let out = dir.join("out.tstats");
    let before = listing(dir);
    let args = render_args(c, dir, &out);
    let r = run(dir, &args);
    let lines: Vec<&str> = r.stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    let mut problems = Vec::new();
    if r.timed_out {
        problems.push(format!("killed after running for {TIME_LIMIT:?}"));
    }
    if r.code != Some(1) {
        problems.push(format!(
            "exit {:?} (want 1; None is a signal, e.g. an abort)",
            r.code
        ));
    }
    for bad in [
        "panicked",
        "overflowed its stack",
        "memory allocation",
        "RUST_BACKTRACE",
    ] {
        if r.stderr.contains(bad) {
            problems.push(format!("stderr contains '{bad}'"));
        }
    }
    if lines.len() != 1 || !lines[0].starts_with("error: ") {
        problems.push("stderr is not exactly one 'error: ' line".into());
    } else if !lines[0].contains(c.want) {
        problems.push(format!("the error does not contain '{}'", c.want));
    }
    if out.exists() || listing(dir) != before {
        problems.push(format!("files left behind: {:?}", listing(dir)));
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{}: {}\n    stderr: {}",
            c.name,
            problems.join("; "),
            r.stderr.trim()
        ))
    }
}

#[test]
fn every_hostile_scene_and_mesh_fails_cleanly() {
    let cases = cases();
    assert!(cases.len() >= 30, "{} cases", cases.len());
    let mut names: Vec<_> = cases.iter().map(|c| c.name).collect();
    names.sort();
    names.dedup();
    assert_eq!(names.len(), cases.len(), "case names must be unique");
    // Two workers: the cases are independent processes.
    let (a, b): (Vec<_>, Vec<_>) = cases.iter().enumerate().partition(|(i, _)| i % 2 == 0);
    let failures: Vec<String> = std::thread::scope(|s| {
        [a, b]
            .map(|part| {
                s.spawn(move || {
                    part.into_iter()
                        .filter_map(|(_, c)| check(c).err())
                        .collect::<Vec<_>>()
                })
            })
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}

/// The harness itself: a valid scene renders under the same limits (so the limits do
/// not make every case fail for the wrong reason), and a case that should fail is
/// caught if it does not.
#[test]
fn the_harness_accepts_a_valid_scene_and_catches_a_wrong_expectation() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    make(dir, "scene.xml", &scene_with(""));
    let c = scene_case("valid", scene_with(""), "");
    let out = dir.join("out.tstats");
    let r = run(dir, &render_args(&c, dir, &out));
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(out.join("manifest.json").is_file());
    assert!(check(&c).unwrap_err().contains("exit Some(0)"));
}

/// Legal but suspicious scenes: exit 0, exactly one `warning:` line naming the problem,
/// and a bundle. Needs the CLI to print `Scene::warnings` (one `warning: ` line each).
#[test]
fn suspicious_scenes_warn_once_and_render() {
    let cases = [
        (
            "radiance_zero",
            scene_with(
                r#"<shape type="cube"><emitter type="area"><rgb name="radiance" value="0"/></emitter></shape>"#,
            ),
            "radiance is zero",
        ),
        (
            "radiance_scaled_to_nothing",
            scene_with(
                r#"<shape type="cube"><emitter type="area"><rgb name="radiance" value="1e-300"/></emitter></shape>"#,
            ),
            "radiance is zero",
        ),
        (
            "point_light_zero",
            scene_with(
                r#"<emitter type="point"><rgb name="intensity" value="0"/><point name="position" x="0" y="0" z="1"/></emitter>"#,
            ),
            "intensity is zero",
        ),
        (
            "shape_without_area",
            scene_with(
                r#"<shape type="cube"><transform name="to_world"><scale value="1e-30"/></transform></shape>"#,
            ),
            "the shape has zero area",
        ),
        (
            "scene_spans_3e-3",
            base_replace(
                r#"<shape type="rectangle">"#,
                r#"<shape type="rectangle"><transform name="to_world"><scale value="1e-3"/></transform>"#,
            ),
            "ray offsets",
        ),
        (
            "time_axis_before_any_light",
            base_replace(
                r#"<float name="bin_width_opl" value="1"/>"#,
                r#"<float name="bin_width_opl" value="1"/><float name="start_opl" value="-10"/>"#,
            ),
            "every bin stays empty",
        ),
        (
            "constant_radiance_zero",
            scene_with(r#"<emitter type="constant"><rgb name="radiance" value="0"/></emitter>"#),
            "radiance is zero",
        ),
        (
            "directional_irradiance_zero",
            scene_with(
                r#"<emitter type="directional"><float name="irradiance" value="0"/></emitter>"#,
            ),
            "irradiance is zero",
        ),
        (
            "envmap_scale_zero",
            scene_with(&format!(
                r#"<emitter type="envmap"><string name="filename" value="{SKY}"/><float name="scale" value="0"/></emitter>"#
            )),
            "is black: this emitter contributes nothing",
        ),
        (
            "reflectance_above_one",
            scene_with(
                r#"<shape type="cube"><bsdf type="diffuse"><rgb name="reflectance" value="2"/></bsdf></shape>"#,
            ),
            "exceeds 1",
        ),
        (
            "sdfgrid_rotated",
            scene_with(
                r#"<shape type="sdfgrid"><string name="filename" value="g.vol"/><transform name="to_world"><rotate z="1" angle="30"/></transform></shape>"#,
            ),
            "Mitsuba 3 warns and renders holes",
        ),
    ];
    let mut failures = Vec::new();
    for (name, scene, want) in cases {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        make(dir, "scene.xml", &scene);
        // The grid the sdfgrid case reads.
        make(dir, "g.vol", &vol_file([2, 2, 2], 1, &SDF8));
        let out = dir.join("out.tstats");
        let c = scene_case(name, scene, want);
        let r = run(dir, &render_args(&c, dir, &out));
        // The scene's own warning, once; the render may add its own (e.g. that
        // nothing landed in the time window), which names no scene line.
        let warnings: Vec<&str> = r
            .stderr
            .lines()
            .filter(|l| l.starts_with("warning: ") && l.contains("scene.xml:"))
            .collect();
        if r.code != Some(0)
            || warnings.len() != 1
            || !warnings[0].contains(want)
            || r.stderr.contains("error")
            || r.stderr.contains("panicked")
            || !out.join("manifest.json").is_file()
        {
            failures.push(format!("{name}: exit {:?}, stderr: {}", r.code, r.stderr));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
