//! Tiny inline meshes in every format, built in code so each test states exactly what it feeds.

use std::path::PathBuf;

/// The unit cube's corners: vertex `i` is `(i & 1, (i >> 1) & 1, (i >> 2) & 1)`.
pub fn cube_positions() -> [[f64; 3]; 8] {
    std::array::from_fn(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
}

/// The cube's six faces as outward, counter-clockwise quads (0-based).
pub const CUBE_QUADS: [[u32; 4]; 6] = [
    [0, 2, 3, 1], // -z
    [4, 5, 7, 6], // +z
    [0, 1, 5, 4], // -y
    [2, 6, 7, 3], // +y
    [0, 4, 6, 2], // -x
    [1, 3, 7, 5], // +x
];

/// The cube's twelve triangles (each quad fanned around its first corner).
pub fn cube_triangles() -> Vec<[u32; 3]> {
    CUBE_QUADS
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect()
}

/// A fresh, empty folder for one test.
pub fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nephele-mesh-io-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The cube as OBJ: every corner form (`v`, `v/vt`, `v//vn`, negative) and extra `v` values.
pub fn cube_obj() -> String {
    let mut s = String::from("# cube\no cube\nvn 0 0 1\nvt 0 0\n");
    for p in cube_positions() {
        s += &format!("v {} {} {} 1.0 0.5 0.5\n", p[0], p[1], p[2]);
    }
    for (i, q) in CUBE_QUADS.iter().enumerate() {
        let corner = |k: usize| match i % 4 {
            0 => format!("{}", q[k] + 1),
            1 => format!("{}/1", q[k] + 1),
            2 => format!("{}//1", q[k] + 1),
            _ => format!("{}/1/1", q[k] as i64 - 8), // relative: -8 is the first vertex
        };
        s += &format!(
            "f {} {} {} {}\n",
            corner(0),
            corner(1),
            corner(2),
            corner(3)
        );
    }
    s
}

/// The cube as NOFF, counts on the header line, normals after positions, colours after faces.
pub fn cube_off() -> String {
    let mut s = String::from("NOFF 8 6 12 # counts on the header line\n");
    for p in cube_positions() {
        s += &format!("{} {} {} 0 0 1\n", p[0], p[1], p[2]);
    }
    for q in CUBE_QUADS {
        s += &format!("4 {} {} {} {} 255 0 0\n", q[0], q[1], q[2], q[3]);
    }
    s
}

/// Binary STL of `tris` over the cube's corners, with `claimed` in the count field. With
/// `solid_header` the 80-byte header starts with "solid", as many exporters do.
pub fn stl_binary(tris: &[[u32; 3]], claimed: u32, solid_header: bool) -> Vec<u8> {
    let p = cube_positions();
    let mut b = if solid_header {
        b"solid cube".to_vec()
    } else {
        b"binary cube".to_vec()
    };
    b.resize(80, b' ');
    b.extend_from_slice(&claimed.to_le_bytes());
    for t in tris {
        b.extend_from_slice(&[0u8; 12]);
        for &v in t {
            for c in p[v as usize] {
                b.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

/// ASCII STL of `tris` over the cube's corners.
pub fn stl_ascii(tris: &[[u32; 3]]) -> String {
    let p = cube_positions();
    let mut s = String::from("solid cube made by hand\n");
    for t in tris {
        s += "  facet normal 0 0 0\n    outer loop\n";
        for &v in t {
            let [x, y, z] = p[v as usize];
            s += &format!("      vertex {x:e} {y:e} {z:e}\n");
        }
        s += "    endloop\n  endfacet\n";
    }
    s + "endsolid cube made by hand\n"
}

/// A PLY with awkward properties: mixed scalar types, lists to skip in the vertex element,
/// an extra element between vertices and faces, and extra face properties.
pub struct Ply {
    /// Vertex positions (written as double x, float32 y, int16 z).
    pub vertices: Vec<[f64; 3]>,
    /// Faces.
    pub faces: Vec<Vec<u32>>,
    /// Counts written in the header, when they should lie.
    pub claimed: Option<(usize, usize)>,
}

impl Ply {
    /// The unit cube with quad faces.
    pub fn cube() -> Ply {
        Ply {
            vertices: cube_positions().to_vec(),
            faces: CUBE_QUADS.iter().map(|q| q.to_vec()).collect(),
            claimed: None,
        }
    }

    /// The cube plus a seventh face.
    pub fn with_face(face: &[u32]) -> Ply {
        let mut p = Ply::cube();
        p.faces.push(face.to_vec());
        p
    }

    /// The cube, but the header claims these counts.
    pub fn cube_claiming(vertices: usize, faces: usize) -> Ply {
        let mut p = Ply::cube();
        p.claimed = Some((vertices, faces));
        p
    }

    /// The header for `format` (`ascii`, `binary_little_endian`...).
    pub fn header(&self, format: &str) -> Vec<u8> {
        let (nv, nf) = self
            .claimed
            .unwrap_or((self.vertices.len(), self.faces.len()));
        format!(
            "ply\nformat {format} 1.0\ncomment made by hand\n\
             element vertex {nv}\nproperty double x\nproperty uchar flag\nproperty float32 y\n\
             property list uchar float junk\nproperty int16 z\n\
             element material 2\nproperty int a\nproperty list uint8 uchar name\n\
             element face {nf}\nproperty uchar red\nproperty list uint16 uint32 vertex_index\n\
             property float q\nend_header\n"
        )
        .into_bytes()
    }

    /// ASCII encoding.
    pub fn ascii(&self) -> Vec<u8> {
        let mut s = String::from_utf8(self.header("ascii")).unwrap();
        for [x, y, z] in &self.vertices {
            s += &format!("{x} 7 {y} 2 0.5 0.25 {z}\n");
        }
        s += "1 3 1 2 3\n2 0\n";
        for f in &self.faces {
            let idx: Vec<String> = f.iter().map(|v| v.to_string()).collect();
            s += &format!("255 {} {} 0.5\n", f.len(), idx.join(" "));
        }
        s.into_bytes()
    }

    /// Binary encoding, little or big endian.
    pub fn binary(&self, big_endian: bool) -> Vec<u8> {
        let mut b = self.header(if big_endian {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        });
        macro_rules! put {
            ($v:expr) => {
                if big_endian {
                    b.extend_from_slice(&$v.to_be_bytes())
                } else {
                    b.extend_from_slice(&$v.to_le_bytes())
                }
            };
        }
        for &[x, y, z] in &self.vertices {
            put!(x);
            put!(7u8);
            put!(y as f32);
            put!(2u8);
            put!(0.5f32);
            put!(0.25f32);
            put!(z as i16);
        }
        for a in [1i32, 2] {
            put!(a);
            put!(1u8);
            put!(b'm');
        }
        for f in &self.faces {
            put!(255u8);
            put!(f.len() as u16);
            for &v in f {
                put!(v);
            }
            put!(0.5f32);
        }
        b
    }
}
