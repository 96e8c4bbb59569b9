//! Per-vertex and per-face attributes of a mesh (Mitsuba 3's mesh attributes), read
//! from PLY files (`scene::ply_attributes`) and looked up by the `mesh_attribute`
//! texture (`textures::mesh_attribute`). Only meshes whose file carries extra
//! properties hold any: `ShapeGeom::Mesh::attributes` is `None` otherwise.
//!
//! Lookup at a hit on triangle `face` with barycentrics (b1, b2), as Mitsuba's
//! `Mesh::interpolate_attribute`: a vertex attribute blends the three vertices' values
//! with weights (1 - b1 - b2, b1, b2) (`fmadd(a0, b0, fmadd(a1, b1, a2 b2))`); a face
//! attribute is the face's value.

/// One named attribute: `dim` floats per vertex or per face, row after row.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshAttribute {
    /// Mitsuba's name: `vertex_NAME` or `face_NAME`.
    pub name: String,
    pub per_vertex: bool,
    /// Channels: 1 or 3 (4 for an RGBA `color`).
    pub dim: usize,
    /// `dim` values per vertex (vertex attributes) or per triangle (face attributes;
    /// a polygon's row repeated for each triangle of its fan).
    pub data: Vec<f32>,
}

/// The attributes of one mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshAttributes {
    pub list: Vec<MeshAttribute>,
}

impl MeshAttributes {
    pub fn get(&self, name: &str) -> Option<&MeshAttribute> {
        self.list.iter().find(|a| a.name == name)
    }

    /// The names, for error messages.
    pub fn names(&self) -> String {
        let v: Vec<&str> = self.list.iter().map(|a| a.name.as_str()).collect();
        if v.is_empty() {
            "none".into()
        } else {
            v.join(", ")
        }
    }
}

impl MeshAttribute {
    /// Channel `c` of this attribute at barycentrics (b1, b2) of triangle `face`
    /// (`tri` its vertex indices).
    #[inline]
    pub fn channel(&self, face: u32, tri: [u32; 3], b1: f32, b2: f32, c: usize) -> f32 {
        if self.per_vertex {
            let at = |v: u32| self.data[v as usize * self.dim + c];
            let b0 = 1.0 - b1 - b2;
            at(tri[0]).mul_add(b0, at(tri[1]).mul_add(b1, at(tri[2]) * b2))
        } else {
            self.data[face as usize * self.dim + c]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_values_blend_by_barycentrics_and_face_values_are_constant() {
        let v = MeshAttribute {
            name: "vertex_w".into(),
            per_vertex: true,
            dim: 1,
            data: vec![1.0, 2.0, 4.0, 100.0],
        };
        // Triangle (0, 1, 3): 1 * 0.5 + 2 * 0.25 + 100 * 0.25.
        assert_eq!(v.channel(0, [0, 1, 3], 0.25, 0.25, 0), 26.0);
        assert_eq!(v.channel(0, [2, 1, 0], 0.0, 0.0, 0), 4.0);
        let f = MeshAttribute {
            name: "face_c".into(),
            per_vertex: false,
            dim: 3,
            data: vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
        };
        assert_eq!(f.channel(1, [0, 1, 2], 0.3, 0.3, 2), 0.6);
        let all = MeshAttributes { list: vec![v, f] };
        assert!(all.get("face_c").is_some() && all.get("face_w").is_none());
        assert_eq!(all.names(), "vertex_w, face_c");
    }
}
