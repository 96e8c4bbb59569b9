//! `shapegroup` + `instance`: an instance is the group's shapes written out with the
//! instance's `to_world` applied after their own; a mirroring instance keeps Mitsuba's
//! normal (the normal transform of the child's), so meshes swap their winding.

use tstat::scene::Overrides;

use crate::common;
use common::{load, run};

fn scene(body: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0,-6,2" target="0,0,0.5" up="0,0,1"/></transform>
    <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
    <film type="transient_hdr_film">
      <integer name="width" value="24"/><integer name="height" value="24"/>
      <integer name="temporal_bins" value="20"/><float name="start_opl" value="4"/><float name="bin_width_opl" value="0.3"/>
    </film>
  </sensor>
  <emitter type="point"><point name="position" x="-2" y="-4" z="3"/><rgb name="intensity" value="40"/></emitter>
  <shape type="rectangle"><transform name="to_world"><scale value="5"/><translate z="-1"/></transform></shape>
  {body}
</scene>"#
    )
}

/// The group's shapes, each with `to_world` = `outer` then its own transform elements.
fn members(outer: &str) -> String {
    format!(
        r#"<shape type="sphere"><float name="radius" value="0.4"/><transform name="to_world"><translate x="-0.8"/>{outer}</transform>
           <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.2, 0.2"/></bsdf></shape>
         <shape type="cylinder"><float name="radius" value="0.3"/><transform name="to_world"><translate x="0.8"/>{outer}</transform></shape>
         <shape type="disk"><transform name="to_world"><scale x="0.5" y="0.3"/><rotate x="1" angle="70"/><translate y="-0.5" z="1"/>{outer}</transform></shape>
         <shape type="cube"><transform name="to_world"><scale value="0.2"/><translate z="0.2"/>{outer}</transform>
           <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.2, 0.8"/></bsdf></shape>"#
    )
}

const OUTERS: [&str; 2] = [
    r#"<rotate z="1" angle="30"/><scale value="0.8"/><translate x="1" y="0.5"/>"#,
    r#"<rotate y="1" angle="-20"/><translate x="-1.2" z="0.3"/>"#,
];

#[test]
fn instances_equal_their_shapes_written_out() {
    let group = format!(
        r#"<shape type="shapegroup" id="g">{}</shape>
           <shape type="instance"><ref id="g"/><transform name="to_world">{}</transform></shape>
           <shape type="instance"><transform name="to_world">{}</transform><ref id="g"/></shape>"#,
        members(""),
        OUTERS[0],
        OUTERS[1]
    );
    let flat = format!("{}{}", members(OUTERS[0]), members(OUTERS[1]));
    let o = Overrides::default();
    let (a, b) = (load(&scene(&group), &o), load(&scene(&flat), &o));
    assert_eq!(a.shapes.len(), b.shapes.len());
    assert_eq!(a.shapes.len(), 9);
    for (s, t) in a.shapes.iter().zip(&b.shapes) {
        let ((lo, hi), (lo2, hi2)) = (s.bounds(), t.bounds());
        assert!(
            (lo - lo2).length() < 1e-5 && (hi - hi2).length() < 1e-5,
            "{}",
            s.name
        );
        assert!((s.area() - t.area()).abs() < 1e-5 * t.area(), "{}", s.name);
        assert_eq!(
            format!("{:?}", a.bsdfs[s.bsdf as usize]),
            format!("{:?}", b.bsdfs[t.bsdf as usize])
        );
    }
    assert_eq!(a.shapes[1].name, "instance#1/shape#0");
    // The renders agree up to the f32 rounding of the twice-mapped geometry.
    let (ra, rb) = (run(&a, 3), run(&b, 3));
    let (sa, sb): (f64, f64) = (ra.steady.iter().sum(), rb.steady.iter().sum());
    assert!(sa > 0.0 && (sa - sb).abs() <= 1e-4 * sa, "{sa} vs {sb}");
    let close = ra
        .steady
        .iter()
        .zip(&rb.steady)
        .filter(|(x, y)| (*x - *y).abs() <= 1e-4 * x.abs().max(1e-3))
        .count();
    assert!(
        close * 100 >= ra.steady.len() * 99,
        "{close} of {}",
        ra.steady.len()
    );
}

#[test]
fn a_mirroring_instance_keeps_the_mapped_normal_of_meshes() {
    let dir = tempfile::tempdir().unwrap();
    // A one-triangle PLY in z = 0 wound counter-clockwise: normal +z.
    std::fs::write(
        dir.path().join("t.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    let path = dir.path().join("s.xml");
    let body = r#"<shape type="shapegroup" id="g"><shape type="ply"><string name="filename" value="t.ply"/><boolean name="face_normals" value="true"/></shape>
        <shape type="rectangle"/></shape>
        <shape type="instance"><ref id="g"/><transform name="to_world"><scale x="1" y="1" z="-1"/><translate z="0.5"/></transform></shape>
        <shape type="instance"><ref id="g"/><transform name="to_world"><scale x="-1" y="1" z="1"/><translate z="0.7"/></transform></shape>"#;
    std::fs::write(&path, scene(body)).unwrap();
    let s = tstat::scene::Scene::load(&path, &Overrides::default()).unwrap();
    // Mitsuba: n' = normalize(M^-T n): (1, 1, -1) maps +z to -z; (-1, 1, 1) keeps +z.
    let n = |i: usize| s.shapes[i].surface(0, 0.2, 0.2, glam::Vec3::ZERO).ng;
    assert!((n(1) + glam::Vec3::Z).length() < 1e-6, "{}", n(1));
    assert!((n(2) + glam::Vec3::Z).length() < 1e-6, "{}", n(2));
    assert!((n(3) - glam::Vec3::Z).length() < 1e-6, "{}", n(3));
    assert!((n(4) - glam::Vec3::Z).length() < 1e-6, "{}", n(4));
}
