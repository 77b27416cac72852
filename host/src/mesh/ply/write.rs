//! Writing a triangle mesh as binary little-endian PLY: the format gridrt reads fastest, and
//! what `gridrt export` writes subdivided meshes in.

use std::io::Write;
use std::path::Path;

use crate::error::{error, Result};
use gridrt_shared::glam::Vec3;

use crate::files::write_atomically;

/// Writes `positions` and `triangles` (indices into `positions`) to `path`, through a
/// temporary file renamed over it.
pub fn write_ply(path: &Path, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<()> {
    let failed = |e: std::io::Error| error!(Output, "{}: cannot write: {e}", path.display());
    write_atomically(path, |temp| {
        let file = std::fs::File::create(temp).map_err(failed)?;
        let mut out = std::io::BufWriter::with_capacity(1 << 20, file);
        write!(
            out,
            "ply\nformat binary_little_endian 1.0\ncomment written by gridrt\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\nelement face {}\n\
             property list uchar uint vertex_indices\nend_header\n",
            positions.len(),
            triangles.len()
        )
        .map_err(failed)?;
        for p in positions {
            for c in p.to_array() {
                out.write_all(&c.to_le_bytes()).map_err(failed)?;
            }
        }
        for t in triangles {
            out.write_all(&[3]).map_err(failed)?;
            for i in t {
                out.write_all(&i.to_le_bytes()).map_err(failed)?;
            }
        }
        out.flush().map_err(failed)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::read_world;
    use crate::mesh::test_util::write_temp;

    #[test]
    fn written_meshes_read_back_exactly() {
        let positions = vec![Vec3::new(1e-30, -2.5, 3.0e38), Vec3::X, Vec3::new(0.1, 0.2, 0.3)];
        let triangles = vec![[0, 1, 2], [2, 1, 0]];
        let path = write_temp("out.ply", b"");
        write_ply(&path, &positions, &triangles).unwrap();
        let (back, cleaning) = read_world(&path).unwrap();
        let back = back.to_f32();
        assert_eq!(cleaning.dropped, 1, "the turned-over copy is dropped");
        assert_eq!(back.positions, positions);
        assert_eq!(back.triangles, vec![[0, 1, 2]]);
    }
}
