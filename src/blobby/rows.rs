//! A blob as a row of twelve numbers, and the checks a blob of a model passes: the layout of
//! the Python binding's `(N, 12)` arrays and the rule of the model file, stated once.

use std::ops::Range;

use glam::{DQuat, DVec3};

use super::Blob;

/// The columns of a blob row ([`Blob::to_row`]): centre x, y, z; rotation quaternion x, y, z,
/// w; semi-axes x, y, z; `a`; `b`.
pub const BLOB_COLUMNS: [&str; 12] = [
    "cx", "cy", "cz", "qx", "qy", "qz", "qw", "sx", "sy", "sz", "a", "b",
];

/// The model file's name of each column's value (`center.x`, …, `a`, `b`).
pub const BLOB_FIELDS: [&str; 12] = [
    "center.x",
    "center.y",
    "center.z",
    "rotation.x",
    "rotation.y",
    "rotation.z",
    "rotation.w",
    "semi_axes.x",
    "semi_axes.y",
    "semi_axes.z",
    "a",
    "b",
];

/// How far a blob's rotation quaternion may be from unit length.
pub const UNIT_TOLERANCE: f64 = 1e-3;

impl Blob {
    /// The blob as a row with [`BLOB_COLUMNS`].
    pub fn to_row(&self) -> [f64; 12] {
        let (c, q, s) = (self.center, self.rotation, self.semi_axes);
        [
            c.x, c.y, c.z, q.x, q.y, q.z, q.w, s.x, s.y, s.z, self.a, self.b,
        ]
    }

    /// The blob of a row with [`BLOB_COLUMNS`] ([`Blob::to_row`]'s inverse, exact); not
    /// checked ([`check_blobs`]).
    pub fn from_row(r: &[f64; 12]) -> Blob {
        Blob {
            center: DVec3::new(r[0], r[1], r[2]),
            rotation: DQuat::from_xyzw(r[3], r[4], r[5], r[6]),
            semi_axes: DVec3::new(r[7], r[8], r[9]),
            a: r[10],
            b: r[11],
        }
    }
}

/// The first thing wrong with a blob of a model ([`check_blobs`]).
#[derive(Clone, Debug, PartialEq)]
pub struct BlobFault {
    /// 0-based index of the blob (its row).
    pub index: usize,
    /// The columns of [`BLOB_COLUMNS`] concerned: one value, or the rotation's four.
    pub columns: Range<usize>,
    /// The model file's name of it: [`BLOB_FIELDS`]' name, or `rotation`.
    pub field: &'static str,
    /// What is wrong, e.g. `is NaN (every value must be finite)`.
    pub problem: String,
}

impl BlobFault {
    /// The names of [`BlobFault::columns`], e.g. `cy` or `qx qy qz qw`.
    pub fn column_names(&self) -> String {
        BLOB_COLUMNS[self.columns.clone()].join(" ")
    }
}

impl std::fmt::Display for BlobFault {
    /// The model file's words: `blob 3: center.y is NaN (…)` (blobs counted from 1).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "blob {}: {} {}",
            self.index + 1,
            self.field,
            self.problem
        )
    }
}

/// Check the blobs of a model: every value finite, semi-axes ≥ 0, `a` > 0, the rotation a
/// unit quaternion (within [`UNIT_TOLERANCE`]). The first fault, by blob then column.
pub fn check_blobs(blobs: &[Blob]) -> Result<(), BlobFault> {
    for (index, b) in blobs.iter().enumerate() {
        let fault = |col: usize, problem: String| BlobFault {
            index,
            columns: col..col + 1,
            field: BLOB_FIELDS[col],
            problem,
        };
        let row = b.to_row();
        for (col, v) in row.iter().enumerate() {
            if v.is_nan() {
                return Err(fault(col, "is NaN (every value must be finite)".into()));
            }
            if v.is_infinite() {
                return Err(fault(col, format!("is {v} (every value must be finite)")));
            }
        }
        for col in 7..10 {
            if row[col] < 0.0 {
                return Err(fault(
                    col,
                    format!("is {} (a semi-axis must be ≥ 0)", row[col]),
                ));
            }
        }
        if !(b.a > 0.0) {
            return Err(fault(10, format!("is {} (it must be > 0)", b.a)));
        }
        let length = b.rotation.length();
        if (length - 1.0).abs() > UNIT_TOLERANCE {
            return Err(BlobFault {
                index,
                columns: 3..7,
                field: "rotation",
                problem: format!("is not a unit quaternion (its length is {length})"),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob() -> Blob {
        Blob {
            center: DVec3::new(1.0, 2.0, 3.0),
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::new(0.5, 0.25, 0.125),
            a: 1.5,
            b: 2.0,
        }
    }

    #[test]
    fn rows_round_trip_exactly() {
        let b = blob();
        assert_eq!(Blob::from_row(&b.to_row()), b);
        assert_eq!(b.to_row()[6], 1.0, "qw");
    }

    #[test]
    fn a_fault_names_the_blob_and_the_field() {
        let mut bad = blob();
        bad.center.y = f64::NAN;
        let f = check_blobs(&[blob(), bad]).unwrap_err();
        assert_eq!(
            (f.index, f.column_names(), f.field),
            (1, "cy".into(), "center.y")
        );
        assert_eq!(
            f.to_string(),
            "blob 2: center.y is NaN (every value must be finite)"
        );
        let mut bad = blob();
        bad.semi_axes.z = -0.5;
        assert_eq!(check_blobs(&[bad]).unwrap_err().column_names(), "sz");
        let mut bad = blob();
        bad.a = 0.0;
        assert_eq!(check_blobs(&[bad]).unwrap_err().field, "a");
        let mut bad = blob();
        bad.rotation = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.5);
        let f = check_blobs(&[bad]).unwrap_err();
        assert_eq!(f.column_names(), "qx qy qz qw");
        assert!(!f.to_string().contains("DQuat"), "{f}");
        assert!(check_blobs(&[blob()]).is_ok());
    }
}
