//! OpenVDB writer: uncompressed grids — the float `density` (`Tree_float_5_4_3`) and, beside it,
//! vector grids such as the velocity `vel` (`Tree_vec3s_5_4_3`, OpenVDB's `Vec3SGrid`).
//!
//! No crate writes OpenVDB, so this is the format written out by hand, as OpenVDB 10 lays it
//! out (file version 224, little-endian, strings as a `u32` length and the bytes):
//!
//! 1. Header: magic `0x56444220` (`i64`), file version 224, library version 10.0, "has grid
//!    offsets" = 1, a 36-character UUID, no file metadata, the grid count.
//! 2. Per grid, its descriptor: name, type (`Tree_float_5_4_3` or `Tree_vec3s_5_4_3`), no
//!    instance parent, and the absolute offsets of the grid, of its voxel data and of its end;
//!    then the grid itself:
//! 3. Compression flags 0 (none); metadata (`class`, e.g. `fog volume`, any further entries —
//!    typed `string`, `double` or `bool`, each a `u32` byte size and the value — and `name`);
//!    the transform, a `UniformScaleTranslateMap` (translation, scale, voxel size, inverse
//!    scale, inverse scale squared, inverse twice the scale — the order of OpenVDB's `Maps.h`).
//! 4. Topology: one buffer; the root (background 0, no tiles, its Internal-5 children in
//!    ascending origin order); each internal node's child mask, value mask (empty), the byte 6
//!    ("no mask compression, all values"), every slot's tile value (0) and its children in slot
//!    order; each leaf's value mask.
//! 5. Voxel data: per leaf in the same order, its value mask, the byte 6 and 512 values (`f32`,
//!    or three `f32` each for a vector grid).
//!
//! Half floats ([`Precision::Half`], [`VdbGrid::with_precision`]): as OpenVDB writes a grid
//! whose `saveFloatAsHalf` is set — the type name gets the suffix `_HalfFloat`
//! (`Tree_float_5_4_3_HalfFloat`), the metadata `is_saved_as_half_float` (bool) is true, and
//! the internal nodes' tile values and the leaves' values are IEEE halves (2 bytes, 6 for a
//! vector); the root's background stays 32-bit. OpenVDB reads the values back as floats.
//!
//! The tree is Root → Internal-5 (32³ slots of 128-voxel Internal-4 nodes) → Internal-4 (16³
//! slots of 8³ leaves) → leaf. A float grid's active voxels are those with a positive value; a
//! vector grid carries its own masks (the velocity's are the density's, so a zero velocity
//! stays active). Everything else is the background 0. The output is a pure function of the
//! grids and the UUID seed.

use std::path::Path;

use super::grid::{DensityGrid, LEAF_VOXELS, Leaf};
use super::velocity::{VELOCITY_GRID_NAME, VectorGrid};

/// OpenVDB file format version written (OpenVDB 10's).
pub const FILE_VERSION: u32 = 224;

/// Log2 of the voxels spanned by an Internal-5 node (`4096 = 2^12`) and an Internal-4 node
/// (`128 = 2^7`), and a leaf (`8 = 2^3`).
const LOG2_SPAN: [u32; 3] = [12, 7, 3];

/// A grid metadata value (OpenVDB's typed metadata: `string`, `double`, `bool`).
#[derive(Clone, Debug, PartialEq)]
pub enum MetaValue {
    /// `StringMetadata`.
    String(String),
    /// `DoubleMetadata`.
    Double(f64),
    /// `BoolMetadata`.
    Bool(bool),
}

/// The values of one grid of a file.
#[derive(Clone, Copy, Debug)]
pub enum GridValues<'a> {
    /// A float grid (`Tree_float_5_4_3`); active where the value is positive.
    Float(&'a DensityGrid),
    /// A vector grid (`Tree_vec3s_5_4_3`, OpenVDB's `Vec3SGrid`); active where its leaves say.
    Vec3(&'a VectorGrid),
}

/// One grid of a VDB file: its name, values and metadata (`name` is added by the writer).
#[derive(Clone, Debug)]
pub struct VdbGrid<'a> {
    /// Grid name, unique in the file.
    pub name: &'a str,
    /// The values and their lattice.
    pub values: GridValues<'a>,
    /// Metadata entries in file order, starting with `class` (e.g. `fog volume`).
    pub metadata: Vec<(String, MetaValue)>,
    /// Values stored as half floats ([`Precision::Half`], see [`VdbGrid::with_precision`]).
    pub half: bool,
}

/// How a VDB grid's values are stored: OpenVDB's `saveFloatAsHalf`, Houdini's "Write 16-bit
/// Floats" (`output.vdb_precision` in a scene).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Precision {
    /// 32-bit floats (the default; the bytes nephele has always written).
    #[default]
    Full,
    /// 16-bit floats (IEEE half): the tree type gets OpenVDB's `_HalfFloat` suffix, the grid the
    /// metadata `is_saved_as_half_float` = true, and every value (leaf voxels and internal tile
    /// values, not the root's background) is written as a half, as OpenVDB's own writer does.
    /// OpenVDB reads them back as 32-bit floats, each within half precision (a relative error
    /// of at most 2⁻¹¹, values under 6.1·10⁻⁵ to within 3·10⁻⁸).
    Half,
}

impl<'a> VdbGrid<'a> {
    /// A fog-volume float grid called `name`.
    pub fn fog(name: &'a str, grid: &'a DensityGrid) -> VdbGrid<'a> {
        VdbGrid {
            name,
            values: GridValues::Float(grid),
            metadata: vec![("class".into(), MetaValue::String("fog volume".into()))],
            half: false,
        }
    }

    /// The grid stored at `precision`: with [`Precision::Half`], its values as half floats and
    /// the metadata `is_saved_as_half_float` (OpenVDB's `Grid::setSaveFloatAsHalf`); with
    /// [`Precision::Full`], unchanged.
    pub fn with_precision(mut self, precision: Precision) -> Self {
        if precision == Precision::Half {
            self.half = true;
            self.metadata.retain(|(k, _)| k != "is_saved_as_half_float");
            self.metadata
                .push(("is_saved_as_half_float".into(), MetaValue::Bool(true)));
        }
        self
    }
}

/// `grid` as the VDB grid `vel` with its metadata (units and kinds: see [`super::velocity`]),
/// for a shot at `fps`; the velocity's counterpart of [`VdbGrid::fog`].
pub fn velocity_vdb_grid(grid: &VectorGrid, fps: f64) -> VdbGrid<'_> {
    let s = |v: &str| MetaValue::String(v.into());
    VdbGrid {
        name: VELOCITY_GRID_NAME,
        values: GridValues::Vec3(grid),
        metadata: vec![
            ("class".into(), s("unknown")),
            ("vector_type".into(), s("contravariant relative")),
            ("is_local_space".into(), MetaValue::Bool(false)),
            ("fps".into(), MetaValue::Double(fps)),
            ("units".into(), s("world units per second")),
        ],
        half: false,
    }
}

/// Write `grid` as an OpenVDB file holding one fog-volume float grid called `name`, atomically.
/// `uuid_seed` makes the file's UUID (the same seed gives the same bytes).
pub fn write_vdb(
    path: &Path,
    grid: &DensityGrid,
    name: &str,
    uuid_seed: u64,
) -> std::io::Result<()> {
    crate::atomic::write_bytes_atomically(path, &encode_vdb(grid, name, uuid_seed))
}

/// Write `grids` as one OpenVDB file, atomically (see [`encode_vdb_grids`]).
pub fn write_vdb_grids(path: &Path, grids: &[VdbGrid], uuid_seed: u64) -> std::io::Result<()> {
    crate::atomic::write_bytes_atomically(path, &encode_vdb_grids(grids, uuid_seed))
}

/// The OpenVDB file's bytes for one fog-volume float grid (see the module doc).
pub fn encode_vdb(grid: &DensityGrid, name: &str, uuid_seed: u64) -> Vec<u8> {
    encode_vdb_grids(&[VdbGrid::fog(name, grid)], uuid_seed)
}

/// The OpenVDB file's bytes for `grids`, in order (see the module doc; each grid is its
/// descriptor followed by its data).
pub fn encode_vdb_grids(grids: &[VdbGrid], uuid_seed: u64) -> Vec<u8> {
    let leaves: usize = grids.iter().map(|g| g.leaf_count()).sum();
    let mut out = Vec::with_capacity(1024 + leaves * (2 * 64 + 1 + 12 * LEAF_VOXELS));
    put_i64(&mut out, 0x5644_4220);
    put_u32(&mut out, FILE_VERSION);
    put_u32(&mut out, 10);
    put_u32(&mut out, 0);
    out.push(1);
    out.extend_from_slice(uuid(uuid_seed).as_bytes());
    put_i32(&mut out, 0);
    put_i32(&mut out, grids.len() as i32);
    for grid in grids {
        write_grid(&mut out, grid);
    }
    out
}

impl VdbGrid<'_> {
    fn leaf_count(&self) -> usize {
        match self.values {
            GridValues::Float(g) => g.leaves.len(),
            GridValues::Vec3(g) => g.leaves.len(),
        }
    }

    /// `(voxel, translation)` of the grid's lattice.
    fn lattice(&self) -> (f64, [f64; 3]) {
        match self.values {
            GridValues::Float(g) => (g.voxel, g.translation),
            GridValues::Vec3(g) => (g.voxel, g.translation),
        }
    }

    /// The tree's type name in the grid descriptor: with half floats, OpenVDB's
    /// `_HalfFloat` suffix (`GridDescriptor::writeHeader`).
    fn tree_type(&self) -> &'static str {
        match (self.values, self.half) {
            (GridValues::Float(_), false) => "Tree_float_5_4_3",
            (GridValues::Vec3(_), false) => "Tree_vec3s_5_4_3",
            (GridValues::Float(_), true) => "Tree_float_5_4_3_HalfFloat",
            (GridValues::Vec3(_), true) => "Tree_vec3s_5_4_3_HalfFloat",
        }
    }

    /// Bytes of one value in memory (the root's background is written at this size, even in
    /// a half-float grid).
    fn value_bytes(&self) -> usize {
        match self.values {
            GridValues::Float(_) => 4,
            GridValues::Vec3(_) => 12,
        }
    }

    /// Bytes of one value as the nodes' buffers store it (internal tile values and leaf
    /// voxels): half that of [`VdbGrid::value_bytes`] in a half-float grid.
    fn stored_value_bytes(&self) -> usize {
        if self.half {
            self.value_bytes() / 2
        } else {
            self.value_bytes()
        }
    }

    fn origins(&self) -> Vec<[i32; 3]> {
        match self.values {
            GridValues::Float(g) => g.leaves.iter().map(|l| l.origin).collect(),
            GridValues::Vec3(g) => g.leaves.iter().map(|l| l.origin).collect(),
        }
    }

    fn mask(&self, leaf: usize) -> [u64; 8] {
        match self.values {
            GridValues::Float(g) => value_mask(&g.leaves[leaf]),
            GridValues::Vec3(g) => g.leaves[leaf].mask,
        }
    }

    fn put_values(&self, out: &mut Vec<u8>, leaf: usize) {
        let values: &[f32] = match self.values {
            GridValues::Float(g) => &g.leaves[leaf].values[..],
            GridValues::Vec3(g) => g.leaves[leaf].values.as_flattened(),
        };
        if self.half {
            values
                .iter()
                .for_each(|&v| out.extend_from_slice(&half::f16::from_f32(v).to_le_bytes()));
        } else {
            values
                .iter()
                .for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        }
    }
}

/// One grid: descriptor (name, type, no instance parent, offsets), then at grid start the
/// compression flags, metadata, transform, topology and, at block start, the voxel data.
fn write_grid(out: &mut Vec<u8>, grid: &VdbGrid) {
    put_str(out, grid.name);
    put_str(out, grid.tree_type());
    put_str(out, "");
    // The three offsets, patched once known.
    let offsets_at = out.len();
    out.extend_from_slice(&[0; 24]);
    let grid_start = out.len();
    put_u32(out, 0);
    let name = ("name".to_string(), MetaValue::String(grid.name.into()));
    let metadata: Vec<&(String, MetaValue)> = grid
        .metadata
        .iter()
        .filter(|(k, _)| k != "name")
        .chain(std::iter::once(&name))
        .collect();
    put_i32(out, metadata.len() as i32);
    for (key, value) in metadata {
        put_str(out, key);
        match value {
            MetaValue::String(v) => {
                put_str(out, "string");
                put_str(out, v);
            }
            MetaValue::Double(v) => {
                put_str(out, "double");
                put_u32(out, 8);
                out.extend_from_slice(&v.to_le_bytes());
            }
            MetaValue::Bool(v) => {
                put_str(out, "bool");
                put_u32(out, 1);
                out.push(u8::from(*v));
            }
        }
    }
    put_str(out, "UniformScaleTranslateMap");
    let (h, translation) = grid.lattice();
    let transform = [
        translation,
        [h; 3],
        [h; 3],
        [1.0 / h; 3],
        [1.0 / (h * h); 3],
        [0.5 / h; 3],
    ];
    for v in transform.iter().flatten() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let origins = grid.origins();
    let tree = Tree::new(&origins);
    tree.write_topology(out, grid.value_bytes(), grid.stored_value_bytes(), |i| {
        grid.mask(i)
    });
    let block_start = out.len();
    // Leaves in the tree's depth-first order (not the grid's origin order).
    for leaf in tree.leaves() {
        grid.mask(leaf)
            .iter()
            .for_each(|w| out.extend_from_slice(&w.to_le_bytes()));
        out.push(6);
        grid.put_values(out, leaf);
    }
    let end = out.len();
    for (n, pos) in [grid_start, block_start, end].into_iter().enumerate() {
        let at = offsets_at + 8 * n;
        out[at..at + 8].copy_from_slice(&(pos as i64).to_le_bytes());
    }
}

/// An Internal-4 node: its slot in its parent and its leaves (indices) with their slots.
type Mid = (usize, Vec<(usize, usize)>);

/// The leaves grouped into Internal-5 and Internal-4 nodes, all in OpenVDB's write order.
struct Tree {
    /// Internal-5 nodes: origin and Internal-4 children.
    tops: Vec<([i32; 3], Vec<Mid>)>,
}

impl Tree {
    /// Group the leaves at `origins` (any order) by their ancestors, each level sorted as
    /// OpenVDB iterates it: root children by origin, internal children by slot.
    fn new(origins: &[[i32; 3]]) -> Tree {
        let mut keyed: Vec<([i32; 3], usize, usize, usize)> = origins
            .iter()
            .enumerate()
            .map(|(i, &o)| {
                let top = align(o, LOG2_SPAN[0]);
                let mid = align(o, LOG2_SPAN[1]);
                (
                    top,
                    slot(mid, top, LOG2_SPAN[1], 5),
                    slot(o, mid, LOG2_SPAN[2], 4),
                    i,
                )
            })
            .collect();
        keyed.sort_by_key(|k| (k.0, k.1, k.2));
        let mut tops: Vec<([i32; 3], Vec<Mid>)> = Vec::new();
        for (top, mid, leaf_slot, leaf) in keyed {
            if tops.last().is_none_or(|t| t.0 != top) {
                tops.push((top, Vec::new()));
            }
            let mids = &mut tops.last_mut().expect("pushed").1;
            if mids.last().is_none_or(|m| m.0 != mid) {
                mids.push((mid, Vec::new()));
            }
            mids.last_mut().expect("pushed").1.push((leaf_slot, leaf));
        }
        Tree { tops }
    }

    /// The leaves (indices) depth-first, in the order OpenVDB reads their voxel data.
    fn leaves(&self) -> impl Iterator<Item = usize> + '_ {
        self.tops
            .iter()
            .flat_map(|t| t.1.iter())
            .flat_map(|m| m.1.iter().map(|l| l.1))
    }

    /// The tree's topology section; the background is `value_bytes` wide, the internal
    /// nodes' tile values `tile_bytes` (both zero), `mask(leaf)` is a leaf's value mask.
    fn write_topology(
        &self,
        out: &mut Vec<u8>,
        value_bytes: usize,
        tile_bytes: usize,
        mask: impl Fn(usize) -> [u64; 8],
    ) {
        put_i32(out, 1); // buffer count
        out.resize(out.len() + value_bytes, 0); // background
        put_u32(out, 0); // tiles
        put_u32(out, self.tops.len() as u32);
        for (origin, mids) in &self.tops {
            origin.iter().for_each(|&c| put_i32(out, c));
            internal_node(out, 5, tile_bytes, mids.iter().map(|m| m.0));
            for (_, leaves) in mids {
                internal_node(out, 4, tile_bytes, leaves.iter().map(|l| l.0));
                for &(_, leaf) in leaves {
                    mask(leaf)
                        .iter()
                        .for_each(|w| out.extend_from_slice(&w.to_le_bytes()));
                }
            }
        }
    }
}

/// An internal node's own topology (masks and tile values, not its children's): `log2` slots
/// per axis, children at `child_slots`, tile values `value_bytes` wide.
fn internal_node(
    out: &mut Vec<u8>,
    log2: u32,
    value_bytes: usize,
    child_slots: impl Iterator<Item = usize>,
) {
    let slots = 1usize << (3 * log2);
    let mut child_mask = vec![0u64; slots / 64];
    for s in child_slots {
        child_mask[s >> 6] |= 1 << (s & 63);
    }
    child_mask
        .iter()
        .for_each(|w| out.extend_from_slice(&w.to_le_bytes()));
    out.resize(out.len() + slots / 8, 0); // value mask: no active tiles
    out.push(6);
    out.resize(out.len() + value_bytes * slots, 0); // tile values: all 0 (background)
}

/// A leaf's value mask: bit `i` set where value `i` is positive.
fn value_mask(leaf: &Leaf) -> [u64; 8] {
    let mut mask = [0u64; 8];
    for (i, &v) in leaf.values.iter().enumerate() {
        if v > 0.0 {
            mask[i >> 6] |= 1 << (i & 63);
        }
    }
    mask
}

/// `c` rounded down to a multiple of `2^log2` (also for negative coordinates).
fn align(c: [i32; 3], log2: u32) -> [i32; 3] {
    c.map(|v| v & !((1 << log2) - 1))
}

/// Slot of the child at `child` inside the node at `node`: children span `2^child_log2` voxels
/// and the node has `2^log2` of them per axis.
fn slot(child: [i32; 3], node: [i32; 3], child_log2: u32, log2: u32) -> usize {
    let [x, y, z] = std::array::from_fn(|a| ((child[a] - node[a]) >> child_log2) as usize);
    (x << (2 * log2)) | (y << log2) | z
}

/// A version-4-shaped UUID string from a seed (deterministic, 36 characters).
fn uuid(seed: u64) -> String {
    let words = [crate::rng::mix64(seed), crate::rng::mix64(!seed)];
    let hex: String = words.iter().map(|w| format!("{w:016x}")).collect();
    format!(
        "{}-{}-4{}-a{}-{}",
        &hex[0..8],
        &hex[8..12],
        &hex[13..16],
        &hex[17..20],
        &hex[20..32]
    )
}

fn put_i32(out: &mut Vec<u8>, v: i32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_i64(out: &mut Vec<u8>, v: i64) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_str(out: &mut Vec<u8>, s: &str) {
    put_u32(out, s.len() as u32);
    out.extend_from_slice(s.as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaf(origin: [i32; 3], set: &[usize]) -> Leaf {
        let mut values = Box::new([0.0; LEAF_VOXELS]);
        for &i in set {
            values[i] = 1.0 + i as f32;
        }
        Leaf { origin, values }
    }

    #[test]
    fn slots_and_alignment_follow_openvdb() {
        assert_eq!(align([-1, 4095, 4096], 12), [-4096, 0, 4096]);
        // Leaf at (8, 16, 24) in the Internal-4 at 0: slot (1 << 8) | (2 << 4) | 3.
        assert_eq!(slot([8, 16, 24], [0; 3], 3, 4), 256 + 32 + 3);
        // Internal-4 at (128, 0, 256) in the Internal-5 at 0: (1 << 10) | 2.
        assert_eq!(slot([128, 0, 256], [0; 3], 7, 5), 1024 + 2);
        assert_eq!(uuid(3).len(), 36);
        assert_eq!(uuid(3), uuid(3));
        assert_ne!(uuid(3), uuid(4));
    }

    #[test]
    fn sizes_and_offsets_are_consistent() {
        let grid = DensityGrid {
            voxel: 0.5,
            translation: [1.0, 2.0, 3.0],
            leaves: vec![leaf([0, 0, 0], &[0, 511]), leaf([-8, 0, 4096], &[7])],
        };
        let bytes = encode_vdb(&grid, "density", 1);
        // Two Internal-5 nodes (one per leaf), each with one Internal-4 child and one leaf.
        let i5 = 2 * 32768 / 8 + 1 + 4 * 32768;
        let i4 = 2 * 4096 / 8 + 1 + 4 * 4096;
        let leaf_topo = 64;
        let leaf_data = 64 + 1 + 4 * 512;
        let topo = 4 + 4 + 4 + 4 + 2 * (12 + i5 + i4 + leaf_topo);
        let i = |at: usize| i64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
        // Offsets follow the descriptor: name, type, parent strings after the 61-byte header.
        let at = 8 + 4 * 3 + 1 + 36 + 4 + 4 + (4 + 7) + (4 + 16) + 4;
        let (grid_start, block, end) = (i(at), i(at + 8), i(at + 16));
        assert_eq!(grid_start, at + 24);
        assert_eq!(end, bytes.len());
        assert_eq!(end - block, 2 * leaf_data);
        let meta = 4 + 4 + 2 * (4 + 6) + (4 + 5) + (4 + 10) + (4 + 4) + (4 + 7);
        let transform = 4 + 24 + 18 * 8;
        assert_eq!(block - grid_start, meta + transform + topo);
        assert_eq!(encode_vdb(&grid, "density", 1), bytes, "deterministic");
        // Full precision is the default's bytes; half stores internal tiles and leaf values in
        // 2 bytes, adds the `_HalfFloat` suffix and the `is_saved_as_half_float` metadata.
        let with =
            |p: Precision| encode_vdb_grids(&[VdbGrid::fog("density", &grid).with_precision(p)], 1);
        assert_eq!(with(Precision::Full), bytes);
        let half = with(Precision::Half);
        let saved = 2 * (2 * 32768 + 2 * 4096 + 2 * 512) - 10 - (4 + 22 + 4 + 4 + 4 + 1);
        assert_eq!(bytes.len() - half.len(), saved);
        assert!(half.windows(26).any(|w| w == b"Tree_float_5_4_3_HalfFloat"));
    }
}
