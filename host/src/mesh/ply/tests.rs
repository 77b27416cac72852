//! Unit tests for the PLY reader, kept apart to keep the reader itself short.

use super::super::test_util::*;
use super::*;
use crate::mesh::Mesh;
use gridrt_shared::glam::Vec3;

/// One data row: the values of one element, each with the type it is stored as.
type Row = Vec<(Scalar, f64)>;

/// A cube as six outward quads, with extra properties and an extra element that the reader must skip.
const HEADER: &str = "comment skip me\nelement vertex 8\nproperty float x\nproperty uchar red\nproperty double y\n\
    property list uchar float extra\nproperty float z\nelement face 6\nproperty uchar flags\n\
    property list uchar int vertex_indices\nelement edge 1\nproperty int a\nproperty int b\n";
const QUADS: [[u32; 4]; 6] = [
    [0, 2, 3, 1],
    [4, 5, 7, 6],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 4, 6, 2],
    [1, 3, 7, 5],
];

fn corner(i: u32) -> Vec3 {
    Vec3::new((i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2 & 1) as f32 * 0.5)
}

fn cube_rows() -> Vec<Row> {
    use Scalar::*;
    let mut rows: Vec<Row> = (0..8u32)
        .map(|i| {
            let p = corner(i).as_dvec3();
            vec![
                (F32, p.x),
                (U8, 200.0),
                (F64, p.y),
                (U8, 2.0),
                (F32, 0.5),
                (F32, -1.0),
                (F32, p.z),
            ]
        })
        .collect();
    rows.extend(QUADS.iter().map(|q| {
        let mut row = vec![(U8, 7.0), (U8, 4.0)];
        row.extend(q.iter().map(|&i| (I32, i as f64)));
        row
    }));
    rows.push(vec![(I32, 0.0), (I32, 1.0)]);
    rows
}

fn encode(format: &str, header: &str, rows: &[Row]) -> Vec<u8> {
    let mut out = format!("ply\nformat {format} 1.0\n{header}end_header\n").into_bytes();
    for row in rows {
        if format == "ascii" {
            let words: Vec<String> = row.iter().map(|(_, v)| v.to_string()).collect();
            out.extend(format!("{}\n", words.join(" ")).bytes());
            continue;
        }
        for &(ty, v) in row {
            let mut b = match ty {
                Scalar::I8 => (v as i8).to_le_bytes().to_vec(),
                Scalar::U8 => (v as u8).to_le_bytes().to_vec(),
                Scalar::I16 => (v as i16).to_le_bytes().to_vec(),
                Scalar::U16 => (v as u16).to_le_bytes().to_vec(),
                Scalar::I32 => (v as i32).to_le_bytes().to_vec(),
                Scalar::U32 => (v as u32).to_le_bytes().to_vec(),
                Scalar::F32 => (v as f32).to_le_bytes().to_vec(),
                Scalar::F64 => v.to_le_bytes().to_vec(),
            };
            if format == "binary_big_endian" {
                b.reverse();
            }
            out.extend(b);
        }
    }
    out
}

fn cube(format: &str) -> Vec<u8> {
    encode(format, HEADER, &cube_rows())
}

#[test]
fn ascii_and_binary_round_trip_to_the_same_mesh() {
    let expected = Mesh {
        positions: (0..8).map(corner).collect(),
        triangles: QUADS
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect(),
    };
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let (mesh, dropped) = load_ok("cube.ply", &cube(format));
        assert_eq!((&mesh, dropped), (&expected, 0), "{format}");
    }
    let single = String::from_utf8(cube("ascii"))
        .unwrap()
        .replace("vertex_indices", "vertex_index");
    assert_eq!(load_ok("single.ply", single.as_bytes()).0, expected);
}

/// The cube's faces as triangle strips, the form some scans come in: one strip per pair of
/// opposite-ish quads joined by a repeated vertex, a restart, and a strip of one quad.
#[test]
fn triangle_strips_read_as_the_same_surface() {
    use Scalar::*;
    let header = "element vertex 8\nproperty float x\nproperty float y\nproperty float z\n\
        element tristrips 1\nproperty list int int vertex_indices\n";
    // Quad [a, b, c, d] (outward, counter-clockwise) is the strip a, b, d, c.
    let strip = |q: [u32; 4]| [q[0], q[1], q[3], q[2]];
    let mut indices: Vec<i64> = Vec::new();
    for pair in QUADS[..4].chunks(2) {
        let (first, second) = (strip(pair[0]), strip(pair[1]));
        indices.extend(first.iter().map(|&i| i as i64));
        // Two repeated points join the strips with triangles of no area and keep the second
        // strip's first triangle at an even place.
        indices.extend([first[3] as i64, second[0] as i64]);
        indices.extend(second.iter().map(|&i| i as i64));
        indices.push(-1);
    }
    for q in &QUADS[4..] {
        indices.extend(strip(*q).iter().map(|&i| i as i64));
        indices.push(-1);
    }
    let mut rows: Vec<Row> = (0..8u32)
        .map(|i| {
            let p = corner(i).as_dvec3();
            vec![(F32, p.x), (F32, p.y), (F32, p.z)]
        })
        .collect();
    let mut list = vec![(I32, indices.len() as f64)];
    list.extend(indices.iter().map(|&i| (I32, i as f64)));
    rows.push(list);
    let facing = |m: &Mesh| -> Vec<(Vec3, [u32; 3])> {
        let mut t: Vec<_> = (m.triangles.iter())
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                let mut sorted = *t;
                sorted.sort();
                ((b - a).cross(c - a).normalize(), sorted)
            })
            .collect();
        t.sort_by_key(|x| x.1);
        t
    };
    let (cube_mesh, _) = load_ok("cube.ply", &cube("ascii"));
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let (mesh, dropped) = load_ok("strips.ply", &encode(format, header, &rows));
        assert_eq!((mesh.triangles.len(), dropped), (12, 0), "{format}");
        // The same six squares, each split along some diagonal, every triangle facing out.
        let (got, want) = (facing(&mesh), facing(&cube_mesh));
        let normals = |f: &[(Vec3, [u32; 3])]| {
            let mut n: Vec<[i32; 3]> = f.iter().map(|(n, _)| n.to_array().map(|x| x.round() as i32)).collect();
            n.sort();
            n
        };
        assert_eq!(normals(&got), normals(&want), "{format}");
    }
    let past = String::from_utf8(encode("ascii", header, &rows))
        .unwrap()
        .replacen(" 7 ", " 9 ", 1);
    expect_err("strip_oob.ply", past.as_bytes(), &["tristrips 0 refers to vertex 9"]);
}

#[test]
fn truncated_data() {
    let ascii = String::from_utf8(cube("ascii")).unwrap();
    let cut = ascii.split_inclusive('\n').take(19).collect::<String>();
    expect_err(
        "trunc.ply",
        cut.as_bytes(),
        &["truncated, or the header's counts are wrong: it declares 8 vertices, 6 faces and 1 'edge' elements (15 lines), the body has 3 lines"],
    );
    let bin = cube("binary_little_endian");
    // Cut inside the fifth face: the edge (8 bytes) and part of the last two faces are missing.
    expect_err(
        "trunc_bin.ply",
        &bin[..bin.len() - 8 - 18 - 4],
        &["truncated: expected 6 faces, file ends after 4"],
    );
    expect_err(
        "trunc_edge.ply",
        &bin[..bin.len() - 2],
        &["truncated: expected 1 'edge' elements, file ends after 0"],
    );
    expect_err(
        "header_only.ply",
        &ascii.as_bytes()[..40],
        &["truncated header: no end_header"],
    );
}

#[test]
fn bad_indices_and_tokens() {
    let ascii = String::from_utf8(cube("ascii")).unwrap();
    let oob = ascii.replace("7 4 0 2 3 1", "7 4 0 2 3 9");
    expect_err(
        "oob.ply",
        oob.as_bytes(),
        &["face 0 refers to vertex 9 but the file has 8 vertices"],
    );
    let neg = ascii.replace("7 4 0 2 3 1", "7 4 0 -2 3 1");
    expect_err("neg.ply", neg.as_bytes(), &["face 0 refers to vertex -2"]);
    let word = ascii.replacen("0 200 0", "0 200 zero", 1);
    expect_err(
        "word.ply",
        word.as_bytes(),
        &["line 17: expected a number for property 'y' of vertex 0, found \"zero\""],
    );
    let float_index = ascii.replace("7 4 0 2 3 1", "7 4 0 2.0 3 1");
    expect_err(
        "floatidx.ply",
        float_index.as_bytes(),
        &["line 25", "'vertex_indices' of face 0", "\"2.0\""],
    );
    let short = ascii.replace("7 4 0 2 3 1", "7 2 0 2");
    expect_err("short.ply", short.as_bytes(), &["face 0 has only 2 vertices"]);
    let nan = ascii.replacen("0 200 0", "0 200 nan", 1);
    expect_err(
        "nan.ply",
        nan.as_bytes(),
        &["line 17: vertex 0 has a non-finite y coordinate NaN"],
    );
    let big = ascii.replacen("0 200 0", "0 200 1e39", 1);
    expect_err(
        "big.ply",
        big.as_bytes(),
        &["line 17: vertex 0: y coordinate 1e39 is beyond the 32-bit float range"],
    );
    let huge = ascii.replace("7 4 0 2 3 1", "7 4 0 2 3 99999999999999999999");
    expect_err(
        "hugeidx.ply",
        huge.as_bytes(),
        &["face 0 refers to vertex 100000000000000000000 but the file has 8 vertices"],
    );
}

#[test]
fn a_line_with_a_value_too_many_or_too_few_is_reported_there() {
    let ascii = String::from_utf8(cube("ascii")).unwrap();
    // Line 18 holds vertex 1.
    let lines: Vec<&str> = ascii.lines().collect();
    assert!(lines[17].starts_with("1 200 0"), "{}", lines[17]);
    let edit = |line: String| {
        let mut l = lines.clone();
        l[17] = &line;
        l.join("\n") + "\n"
    };
    expect_err(
        "long.ply",
        edit(format!("{} 9", lines[17])).as_bytes(),
        &["line 18: vertex 1 has more values than the header declares, starting at \"9\""],
    );
    let short = lines[17].rsplit_once(' ').unwrap().0.to_string();
    expect_err(
        "short_line.ply",
        edit(short).as_bytes(),
        &["line 18: vertex 1 ends before its property 'z'"],
    );
    // Blank lines between elements and trailing blanks are fine.
    let airy = ascii
        .replace("\n1 200", "\n\n  \n1 200")
        .replace(" -1 0\n", " -1 0 \t\r\n");
    assert_eq!(load_ok("airy.ply", airy.as_bytes()).0.triangles.len(), 12);
}

#[test]
fn bad_headers() {
    let ascii = String::from_utf8(cube("ascii")).unwrap();
    let bad = |name: &str, from: &str, to: &str, needles: &[&str]| {
        assert!(ascii.contains(from), "{from}");
        expect_err(name, ascii.replacen(from, to, 1).as_bytes(), needles);
    };
    bad("magic.ply", "ply\n", "plx\n", &["bad magic", "\"plx\""]);
    bad(
        "fmt.ply",
        "ascii 1.0",
        "binary_middle_endian 1.0",
        &["unsupported PLY format"],
    );
    bad("ver.ply", "ascii 1.0", "ascii 2.0", &["unsupported PLY format"]);
    bad("noformat.ply", "format ascii 1.0\n", "", &["no format line"]);
    bad(
        "type.ply",
        "property uchar red",
        "property colour red",
        &["header line 6", "unknown property type"],
    );
    bad(
        "count.ply",
        "element vertex 8",
        "element vertex eight",
        &["header line 4", "element count"],
    );
    bad(
        "nox.ply",
        "property float x\n",
        "",
        &["vertex element has no property 'x'"],
    );
    bad(
        "noz.ply",
        "property float z\n",
        "property float w\n",
        &["no property 'z'"],
    );
    bad(
        "nofaces.ply",
        "element face 6",
        "element facet 6",
        &["no triangles", "no 'element face' or 'element tristrips'"],
    );
    bad(
        "noidx.ply",
        "int vertex_indices",
        "int corners",
        &["no property 'vertex_indices'"],
    );
    bad(
        "fltidx.ply",
        "uchar int vertex_indices",
        "uchar float vertex_indices",
        &["list of integers"],
    );
    bad(
        "keyword.ply",
        "comment skip me",
        "commentary",
        &["header line 3", "unknown header line"],
    );
    bad(
        "orphan.ply",
        "comment skip me",
        "property float q",
        &["property before any element"],
    );
    expect_err("zero.ply", b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n", &["no triangles"]);
}

#[test]
fn hostile_counts_and_garbage_never_panic() {
    let huge = "ply\nformat binary_little_endian 1.0\nelement nothing 18446744073709551615\n\
        element vertex 18446744073709551615\nproperty float x\nproperty float y\nproperty float z\n\
        element face 1\nproperty list uint uint vertex_indices\nend_header\n\0\0\0\0";
    expect_err(
        "huge.ply",
        huge.as_bytes(),
        &["truncated: expected 18446744073709551615 vertices, file ends after 0"],
    );
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    for round in 0..200 {
        let bytes = cube(["ascii", "binary_little_endian"][round % 2]);
        load_scrambled("fuzz.ply", bytes, &mut seed, 1 + round % 4);
    }
}
