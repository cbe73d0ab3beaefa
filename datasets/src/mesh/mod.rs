//! Triangle meshes, as phone scans (the iPhone "3D Scanner App") export
//! them: a textured Wavefront OBJ read into one mesh with a colour per
//! vertex ([`read_obj`]), its vertices as a point cloud, and a ray caster
//! ([`Raycaster`]) rendering z-depth images of it for any camera.

mod obj;
mod raycast;
mod texture;

pub use obj::read_obj;
pub use raycast::Raycaster;

use crate::points::PointCloud;

/// A triangle mesh in metres, in the capture's world frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Each triangle's three indices into [`TriangleMesh::positions`]
    /// (either winding).
    pub triangles: Vec<[u32; 3]>,
    /// 8-bit colour per vertex (from the texture at the vertex's UV, else
    /// the OBJ's own vertex colours), `None` when there is none.
    pub colors: Option<Vec<[u8; 3]>>,
}

/// A mesh read from a file with what the reader had to say once (e.g. that
/// the texture is missing, so the cloud has no colour).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeshFile {
    /// The mesh.
    pub mesh: TriangleMesh,
    /// Remarks for the user, each naming the file, each once.
    pub notes: Vec<String>,
}

impl TriangleMesh {
    /// The vertices as a point cloud: positions and colours, no labels.
    pub fn point_cloud(&self) -> PointCloud {
        PointCloud {
            positions: self.positions.clone(),
            colors: self.colors.clone(),
            labels: None,
        }
    }
}
