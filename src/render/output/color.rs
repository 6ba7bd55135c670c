//! The RGB spaces of the EXR frames: the renderer works in linear Rec.709 (sRGB primaries, D65
//! white); `output.colorspace: ACEScg` writes the EXR's linear values in ACES AP1 instead.
//!
//! The conversion is exact, derived from the two spaces' chromaticities (their RGB → XYZ
//! matrices from primaries and white point) with a Bradford adaptation from D65 to the ACES
//! white: `M = XYZ→AP1 · Bradford(D65 → ACES white) · Rec.709→XYZ`. That is the matrix of
//! OpenColorIO's ACES configs (`lin_rec709` → `ACEScg`) and of colour-science, to their printed
//! digits. Each EXR carries the `chromaticities` of the space it holds.
//!
//! References: SMPTE RP 177 (RGB → XYZ from chromaticities); ITU-R BT.709; the ACES AP1
//! primaries (SMPTE ST 2065-1 / Academy S-2014-004); K. M. Lam (1985) for Bradford.

use glam::{DMat3, DVec3, Mat3, Vec3};
use serde::{Deserialize, Serialize};

/// CIE xy chromaticities of a space's red, green and blue primaries and its white point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Chromaticities {
    /// Red primary `(x, y)`.
    pub red: [f64; 2],
    /// Green primary.
    pub green: [f64; 2],
    /// Blue primary.
    pub blue: [f64; 2],
    /// White point.
    pub white: [f64; 2],
}

/// Rec.709 / sRGB primaries with the D65 white (OpenEXR's default chromaticities).
pub(crate) const REC709: Chromaticities = Chromaticities {
    red: [0.64, 0.33],
    green: [0.30, 0.60],
    blue: [0.15, 0.06],
    white: [0.3127, 0.3290],
};

/// ACES AP1 primaries (ACEScg) with the ACES white (≈ D60).
pub(crate) const AP1: Chromaticities = Chromaticities {
    red: [0.713, 0.293],
    green: [0.165, 0.830],
    blue: [0.128, 0.044],
    white: [0.32168, 0.33767],
};

/// The linear RGB space of the EXR frames (the scene file's `output.colorspace`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ColorSpace {
    /// Linear Rec.709 primaries, D65 white: the renderer's own space.
    #[default]
    Rec709,
    /// ACEScg: linear ACES AP1 primaries, ACES white.
    ACEScg,
}

impl ColorSpace {
    /// The space's chromaticities (what the EXR's `chromaticities` attribute says).
    pub(crate) fn chromaticities(self) -> Chromaticities {
        match self {
            ColorSpace::Rec709 => REC709,
            ColorSpace::ACEScg => AP1,
        }
    }

    /// The OpenColorIO role-style name written in the EXR (`nephele/colorspace`).
    pub fn name(self) -> &'static str {
        match self {
            ColorSpace::Rec709 => "lin_rec709",
            ColorSpace::ACEScg => "ACEScg",
        }
    }

    /// The matrix taking the renderer's linear Rec.709 to this space (identity for Rec.709).
    pub fn from_rec709(self) -> DMat3 {
        match self {
            ColorSpace::Rec709 => DMat3::IDENTITY,
            other => conversion(&REC709, &other.chromaticities()),
        }
    }

    /// The conversion of the renderer's linear Rec.709 values to this space as the EXR writer
    /// applies it (and so the Python binding's arrays): the f32 matrix times the value, and the
    /// value untouched for Rec.709.
    pub fn converter(self) -> RgbConverter {
        RgbConverter {
            space: self,
            matrix: self.from_rec709().as_mat3(),
        }
    }
}

/// Linear Rec.709 RGB to a [`ColorSpace`], in single precision ([`ColorSpace::converter`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RgbConverter {
    space: ColorSpace,
    matrix: Mat3,
}

impl RgbConverter {
    /// `rgb` (linear Rec.709) in the converter's space: bit for bit what the EXR stores.
    pub fn apply(&self, rgb: [f32; 3]) -> [f32; 3] {
        match self.space {
            ColorSpace::Rec709 => rgb,
            _ => (self.matrix * Vec3::from(rgb)).to_array(),
        }
    }
}

/// The RGB → XYZ matrix of a space (SMPTE RP 177): columns are the primaries' XYZ, scaled so
/// that RGB `(1, 1, 1)` is the white point with `Y = 1`.
pub(crate) fn rgb_to_xyz(c: &Chromaticities) -> DMat3 {
    let xyz = |[x, y]: [f64; 2]| DVec3::new(x / y, 1.0, (1.0 - x - y) / y);
    let primaries = DMat3::from_cols(xyz(c.red), xyz(c.green), xyz(c.blue));
    let scale = primaries.inverse() * xyz(c.white);
    DMat3::from_cols(
        primaries.x_axis * scale.x,
        primaries.y_axis * scale.y,
        primaries.z_axis * scale.z,
    )
}

/// Bradford chromatic adaptation of XYZ from white `from` to white `to` (xy).
pub(crate) fn bradford(from: [f64; 2], to: [f64; 2]) -> DMat3 {
    // Rows of the Bradford cone response matrix.
    let ma = DMat3::from_cols_array(&[
        0.8951, -0.7502, 0.0389, //
        0.2664, 1.7135, -0.0685, //
        -0.1614, 0.0367, 1.0296,
    ]);
    let xyz = |[x, y]: [f64; 2]| DVec3::new(x / y, 1.0, (1.0 - x - y) / y);
    let (s, d) = (ma * xyz(from), ma * xyz(to));
    ma.inverse() * DMat3::from_diagonal(d / s) * ma
}

/// The linear RGB conversion from space `from` to space `to`, adapting the white by Bradford.
pub(crate) fn conversion(from: &Chromaticities, to: &Chromaticities) -> DMat3 {
    rgb_to_xyz(to).inverse() * bradford(from.white, to.white) * rgb_to_xyz(from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rec709_to_acescg_is_the_published_matrix() {
        // OpenColorIO's ACES 1.x config (`lin_srgb` → ACEScg) and colour-science's
        // RGB_to_RGB(sRGB, ACEScg, "Bradford"), 7 printed digits.
        let published = [
            [0.613_097_4, 0.339_523_1, 0.047_379_5],
            [0.070_193_7, 0.916_353_9, 0.013_452_4],
            [0.020_615_6, 0.109_569_8, 0.869_814_6],
        ];
        let m = ColorSpace::ACEScg.from_rec709();
        for (r, row) in published.iter().enumerate() {
            for (c, &want) in row.iter().enumerate() {
                let got = m.col(c)[r];
                assert!((got - want).abs() < 1e-6, "[{r}][{c}] {got} vs {want}");
            }
        }
        // White stays white (rows sum to 1), and the identity is exact for Rec.709.
        let white = m * DVec3::ONE;
        assert!((white - DVec3::ONE).abs().max_element() < 1e-12, "{white}");
        assert_eq!(ColorSpace::Rec709.from_rec709(), DMat3::IDENTITY);
    }
}
