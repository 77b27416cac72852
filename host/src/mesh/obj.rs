//! Wavefront OBJ via `tobj`, behind a strict pre-pass of our own.
//!
//! tobj reports errors without line, face or index ("face vertex index out of bounds"), splits the mesh at every
//! `o`/`g`/`usemtl` (duplicating the vertices the parts share) and may follow `mtllib` to other files. So the
//! pre-pass checks every `v` and `f` line itself, with line numbers, and hands tobj a canonical buffer holding only
//! `v x y z` and `f i j k ...` lines with absolute 1-based indices: one model, no materials, nothing left to fail.
//! Coordinates are read in double precision. A line whose statement is not OBJ's, or is OBJ's but shapes a surface
//! gridrt cannot draw (free-form curves and surfaces, another file called in), is an error naming the line: skipping
//! it would drop faces without a word.

use std::io::Cursor;

use crate::error::{error, fail, Result};
use gridrt_shared::glam::DVec3;

use super::{is_integer, quote, WorldMesh};

/// Parses an OBJ file's bytes into positions and counter-clockwise triangles (polygons are fan-triangulated).
/// Only vertices that some face uses are kept, in order of first use. Errors carry no file name; the caller adds it.
pub fn parse_obj(bytes: &[u8]) -> Result<WorldMesh> {
    // Lossy, so that stray Latin-1 in comments or names does not reject a file; a damaged number still fails.
    let text = String::from_utf8_lossy(bytes);
    // A byte-order mark would otherwise glue itself to the first line's keyword.
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let total = check_vertices(text)?;
    let canonical = canonicalize(text, total)?;
    // Spelled out in full today; the update stays for the fields tobj's `merging`/`reordering` features add.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let (models, _) = tobj::load_obj_buf(&mut Cursor::new(canonical), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| error!(Input, "{e} (reported by tobj)"))?;

    let mut mesh = WorldMesh::default();
    for model in models {
        let base = mesh.positions.len() as u32;
        let (positions, _) = model.mesh.positions.as_chunks::<3>();
        mesh.positions.extend(positions.iter().map(|&p| DVec3::from_array(p)));
        let (triangles, _) = model.mesh.indices.as_chunks::<3>();
        mesh.triangles.extend(triangles.iter().map(|t| t.map(|i| base + i)));
    }
    Ok(mesh)
}

/// Checks that every `v` line starts with three finite numbers; returns how many vertices the file has.
fn check_vertices(text: &str) -> Result<usize> {
    let mut count = 0usize;
    for (line_no, line) in (1..).zip(text.lines()) {
        let mut words = line.split_whitespace();
        if words.next() != Some("v") {
            continue;
        }
        count += 1;
        for axis in ["x", "y", "z"] {
            let word = words
                .next()
                .ok_or_else(|| error!(Input, "line {line_no}: vertex {count} has no {axis} coordinate"))?;
            let value: f64 = word.parse().map_err(|_| {
                error!(
                    Input,
                    "line {line_no}: vertex {count} has a non-numeric {axis} coordinate {}",
                    quote(word)
                )
            })?;
            if !value.is_finite() {
                fail!(
                    Input,
                    "line {line_no}: vertex {count} has a non-finite {axis} coordinate {}",
                    quote(word)
                );
            }
            if value.abs() > f32::MAX as f64 {
                fail!(
                    Input,
                    "line {line_no}: vertex {count}: {axis} coordinate {} is beyond the 32-bit float range (+-3.4e38)",
                    quote(word)
                );
            }
        }
    }
    Ok(count)
}

/// Rewrites the file as `v`/`f` lines only, resolving relative indices and checking every index against `total`.
fn canonicalize(text: &str, total: usize) -> Result<String> {
    let mut out = String::with_capacity(text.len());
    let mut vertices_so_far = 0usize;
    let mut faces = 0usize;
    for (line_no, line) in (1..).zip(text.lines()) {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                vertices_so_far += 1;
                let xyz: Vec<&str> = words.take(3).collect();
                out.push_str("v ");
                out.push_str(&xyz.join(" "));
                out.push('\n');
            }
            // `fo` is an old spelling of `f`.
            Some("f" | "fo") => {
                faces += 1;
                let mut refs = 0;
                out.push('f');
                for word in words {
                    let index = resolve(word, vertices_so_far, total)
                        .map_err(|problem| error!(Input, "face {faces} {problem} (line {line_no})"))?;
                    out.push_str(&format!(" {index}"));
                    refs += 1;
                }
                if refs < 3 {
                    fail!(Input, "face {faces} has only {refs} vertices (line {line_no})");
                }
                out.push('\n');
            }
            // Normals, texture coordinates, groups, materials, points and lines do not shape the surface.
            Some(word) if IGNORED.contains(&word) || word.starts_with('#') => {}
            Some(word) if UNSUPPORTED.contains(&word) => fail!(
                Input,
                "line {line_no}: the OBJ statement {} is not supported (free-form curves and surfaces, and other \
                 files called in, are not drawn; gridrt reads polygons)",
                quote(word)
            ),
            Some(word) => fail!(
                Input,
                "line {line_no}: unknown statement {} (an OBJ line starts with v, f, vt, vn, g, o, s, usemtl, ...)",
                quote(word)
            ),
            None => {}
        }
    }
    Ok(out)
}

/// OBJ statements that do not shape a polygonal surface: skipped.
const IGNORED: &[&str] = &[
    "vt",
    "vn",
    "vp",
    "l",
    "p",
    "g",
    "o",
    "s",
    "mg",
    "usemtl",
    "mtllib",
    "usemap",
    "maplib",
    "lod",
    "bevel",
    "c_interp",
    "d_interp",
    "shadow_obj",
    "trace_obj",
];

/// OBJ statements that shape surfaces gridrt does not draw: free-form geometry, and other
/// files called in.
const UNSUPPORTED: &[&str] = &[
    "cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp", "end", "con",
    "ctech", "stech", "call", "csh",
];

/// Turns one face word (`7`, `7/1`, `7//3`, `-2/...`) into an absolute 1-based vertex index.
/// `before` is the number of vertices defined above the face, which relative indices count back from.
fn resolve(word: &str, before: usize, total: usize) -> std::result::Result<usize, String> {
    let head = word.split('/').next().unwrap_or_default();
    let raw: i64 = match head.parse() {
        Ok(raw) => raw,
        // All digits, but beyond 64 bits: a number, just far past any vertex.
        Err(_) if is_integer(head) => {
            return Err(format!(
                "refers to vertex {} but the file has {total} vertices",
                quote(head)
            ))
        }
        Err(_) => return Err(format!("has a non-numeric vertex reference {}", quote(word))),
    };
    let index = match raw {
        0 => return Err("refers to vertex 0 but OBJ indices start at 1".into()),
        // OBJ allows positive indices to point below the face; tobj resolves them after reading the whole file.
        1.. => raw as u64,
        _ => {
            let back = raw.unsigned_abs();
            if back > before as u64 {
                return Err(format!("refers to vertex {raw} but only {before} vertices precede it"));
            }
            before as u64 + 1 - back
        }
    };
    if index > total as u64 {
        return Err(format!("refers to vertex {raw} but the file has {total} vertices"));
    }
    Ok(index as usize)
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use gridrt_shared::glam::Vec3;

    const SQUARE: &[u8] = b"# unit square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    fn obj(body: &str) -> Vec<u8> {
        [SQUARE, body.as_bytes()].concat()
    }

    #[test]
    fn quads_and_polygons_are_triangulated_counter_clockwise() {
        let (m, dropped) = load_ok("quad.obj", &obj("f 1 2 3 4\n"));
        assert_eq!(dropped, 0);
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles.len(), 2);
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            assert!((b - a).cross(c - a).z > 0.0, "triangle {t:?} is not counter-clockwise");
        }
        let (m, _) = load_ok("penta.obj", &obj("v 0.5 1.5 0\nf 1 2 3 5 4\n"));
        assert_eq!(m.triangles.len(), 3);
    }

    #[test]
    fn index_forms_and_groups_share_vertices() {
        let body = "vt 0 0\nvn 0 0 1\no first\nusemtl a\nf 1/1/1 2/1/1 3//1\ng second\nf -4 -2 -1\ns 1\nl 1 2\np 1\n";
        let (m, _) = load_ok("forms.obj", &obj(body));
        assert_eq!(
            m.positions.len(),
            4,
            "groups must not duplicate the vertices they share"
        );
        assert_eq!(m.triangles.len(), 2);
        let corners: Vec<[Vec3; 3]> = m.triangles.iter().map(|t| t.map(|i| m.positions[i as usize])).collect();
        assert_eq!(corners[1], [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]);
    }

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let (m, _) = load_ok("bom.obj", b"\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        assert_eq!(m.positions[0], Vec3::ZERO);
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn forward_references_and_crlf_are_accepted() {
        let (m, _) = load_ok("fwd.obj", b"f 1 2 3\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\n");
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn index_out_of_range() {
        expect_err(
            "oob.obj",
            &obj("f 1 2 3\nf 1 2 900\n"),
            &["face 2 refers to vertex 900 but the file has 4 vertices"],
        );
        expect_err(
            "zero.obj",
            &obj("f 0 1 2\n"),
            &["face 1 refers to vertex 0", "start at 1"],
        );
        expect_err(
            "rel.obj",
            &obj("f -1 -2 -9\n"),
            &["face 1 refers to vertex -9 but only 4 vertices precede it"],
        );
        expect_err(
            "huge.obj",
            &obj("f 1 2 99999999999999999999\n"),
            &[
                "face 1 refers to vertex \"99999999999999999999\" but the file has 4 vertices",
                "line 6",
            ],
        );
        expect_err(
            "past_u32.obj",
            &obj("f 1 2 4294967297\n"),
            &["face 1 refers to vertex 4294967297 but the file has 4 vertices"],
        );
    }

    #[test]
    fn malformed_lines() {
        expect_err(
            "nonnum.obj",
            &obj("v 1 oops 2\nf 1 2 3\n"),
            &["line 6", "vertex 5", "non-numeric y", "\"oops\""],
        );
        expect_err("short.obj", &obj("v 1 2\nf 1 2 3\n"), &["line 6", "vertex 5 has no z"]);
        expect_err(
            "nan.obj",
            &obj("v 1 NaN 2\nf 1 2 3\n"),
            &["line 6", "vertex 5", "non-finite", "NaN"],
        );
        expect_err(
            "big.obj",
            &obj("v 1 1e39 2\nf 1 2 3\n"),
            &[
                "line 6",
                "vertex 5",
                "vertex 5: y coordinate \"1e39\" is beyond the 32-bit float range",
            ],
        );
        expect_err(
            "inf.obj",
            &obj("v 1 2 -inf\nf 1 2 3\n"),
            &["line 6", "vertex 5", "non-finite z coordinate \"-inf\""],
        );
        expect_err(
            "badref.obj",
            &obj("f 1 x/2 3\n"),
            &["face 1 has a non-numeric vertex reference \"x/2\"", "line 6"],
        );
        expect_err("noref.obj", &obj("f 1 //2 3\n"), &["face 1", "non-numeric"]);
        expect_err("twoverts.obj", &obj("f 1 2\n"), &["face 1 has only 2 vertices"]);
        expect_err("nofaces.obj", SQUARE, &["no triangles"]);
        expect_err("comment.obj", b"# nothing here\n", &["no triangles"]);
    }

    #[test]
    fn garbage_never_panics() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for round in 0..40 {
            load_scrambled("fuzz.obj", obj("f 1 2 3 4\n"), &mut seed, 1 + round % 5);
        }
    }
}
