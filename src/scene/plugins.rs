//! The plugin table: every plugin type tstat reads, by element tag. The loader and
//! `tstat check` both read it, so a plugin is supported exactly when it is listed here.

/// Plugin types each loader accepts (by element tag).
pub const SUPPORTED: &[(&str, &[&str])] = &[
    (
        "bsdf",
        &[
            "diffuse",
            "dielectric",
            "roughdielectric",
            "thindielectric",
            "conductor",
            "roughconductor",
            "plastic",
            "roughplastic",
            "null",
            "twosided",
            "mask",
            "Separable",
            "Composed",
            "blendbsdf",
            "normalmap",
            "bumpmap",
            "pplastic",
            "polarizer",
            "principled",
            "principledthin",
        ],
    ),
    (
        "shape",
        &[
            "rectangle",
            "cube",
            "sphere",
            "disk",
            "cylinder",
            "linearcurve",
            "bsplinecurve",
            "ply",
            "obj",
            "serialized",
            "sdfgrid",
            "shapegroup",
            "instance",
        ],
    ),
    (
        "texture",
        &["bitmap", "checkerboard", "mesh_attribute", "rawconstant"],
    ),
    (
        "emitter",
        &[
            "area",
            "angulararea",
            "point",
            "spot",
            "projector",
            "envmap",
            "constant",
            "directional",
        ],
    ),
    (
        "sensor",
        &[
            "perspective",
            "thinlens",
            "orthographic",
            "nlos_capture_meter",
        ],
    ),
    ("film", &["transient_hdr_film"]),
    (
        "sampler",
        &[
            "independent",
            "stratified",
            "multijitter",
            "orthogonal",
            "ldsampler",
        ],
    ),
    ("rfilter", &["box"]),
    (
        "integrator",
        &[
            "transient_path",
            "transient_prbvolpath",
            "transient_nlos_path",
        ],
    ),
    (
        "TemporalProfile",
        &["ConstantTP", "ExponentialTP", "EpanechnikovTP", "PosEpanTP"],
    ),
    ("medium", &["homogeneous", "heterogeneous"]),
    ("volume", &["constvolume", "gridvolume"]),
    ("phase", &["isotropic", "hg"]),
];

/// A plugin type as the loaders spell it: a supported plugin's name written in
/// another case ("Rectangle", "separable") becomes its spelling in [`SUPPORTED`], as
/// Mitsuba finds plugins on Windows and macOS, whose file systems ignore case; any
/// other name stays as written.
pub fn canonical_plugin_name(name: String) -> String {
    SUPPORTED
        .iter()
        .flat_map(|(_, types)| types.iter())
        .find(|t| t.eq_ignore_ascii_case(&name))
        .map_or(name, |t| t.to_string())
}
