//! What a frame is rendered into besides its size: the window of pixels to render (a region of
//! the full image, for look tests) and the outputs beside the beauty — the render passes and
//! the ID mattes ([`crate::render::output::cryptomatte`]). pbrt's `Film` holds the same: resolution, crop
//! window and the outputs a pixel writes.
//!
//! A region renders exactly the pixels a full frame has there, bit for bit: the integrator
//! renders the full frame's tiles that meet the window (each culled against its whole tile's
//! frustum, as in the full frame) and only their pixels inside it; every pixel keeps its own
//! generator, seeded by its index in the full frame.

use crate::render::output::cryptomatte::Mattes;

/// A window of a frame's pixels: columns `x0..x1` and rows `y0..y1` (half-open, `x1`, `y1`
/// exclusive), row 0 at the top, inside the full image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Region {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl Region {
    /// The whole `width × height` image.
    pub fn full(width: u32, height: u32) -> Region {
        Region {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
    }

    /// Parse `x0,y0,x1,y1` (pixels of a `width × height` frame, `x1`, `y1` exclusive) and check
    /// that it is a non-empty window inside the frame; the error says what is wrong.
    pub(crate) fn parse(text: &str, width: u32, height: u32) -> Result<Region, String> {
        let parts: Vec<&str> = text.split(',').map(str::trim).collect();
        let malformed = || {
            format!(
                "'{text}' is not x0,y0,x1,y1 (four whole numbers of pixels, x1 and y1 exclusive)"
            )
        };
        if parts.len() != 4 {
            return Err(malformed());
        }
        let mut v = [0u32; 4];
        for (slot, part) in v.iter_mut().zip(&parts) {
            *slot = part.parse().map_err(|_| malformed())?;
        }
        let r = Region {
            x0: v[0],
            y0: v[1],
            x1: v[2],
            y1: v[3],
        };
        if r.x1 <= r.x0 || r.y1 <= r.y0 {
            return Err(format!(
                "'{text}' is empty: need x0 < x1 and y0 < y1 (x1 and y1 exclusive)"
            ));
        }
        if r.x1 > width || r.y1 > height {
            return Err(format!(
                "'{text}' is outside the {width}×{height} frame (x1 ≤ {width}, y1 ≤ {height})"
            ));
        }
        Ok(r)
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    /// True when pixel `(x, y)` is inside.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        (self.x0..self.x1).contains(&x) && (self.y0..self.y1).contains(&y)
    }

    /// The part of `other` inside this window, `None` when they do not meet.
    pub(crate) fn intersect(&self, other: &Region) -> Option<Region> {
        let r = Region {
            x0: self.x0.max(other.x0),
            y0: self.y0.max(other.y0),
            x1: self.x1.min(other.x1),
            y1: self.y1.min(other.y1),
        };
        (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
    }
}

impl std::fmt::Display for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.y0, self.x1, self.y1)
    }
}

/// A frame's window and its outputs beside the beauty (the default: the whole frame, beauty
/// only).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Film {
    /// Render only these pixels (`None`: the whole frame).
    pub region: Option<Region>,
    /// Also make the render passes ([`crate::render::Passes`]).
    pub passes: bool,
    /// Also make these ID mattes ([`crate::render::output::cryptomatte::IdMattes`]).
    pub mattes: Option<Mattes>,
    /// Also make the motion vectors ([`crate::render::Frame::motion`]), from the
    /// [`crate::render::FrameOptions::motion`] source (0 without one).
    pub motion: bool,
}

impl Film {
    /// The window rendered in a `width × height` frame.
    pub fn window(&self, width: u32, height: u32) -> Region {
        self.region.unwrap_or(Region::full(width, height))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_parse_and_are_checked_against_the_frame() {
        let r = Region::parse("2, 3,10,7", 16, 9).unwrap();
        assert_eq!((r.x0, r.y0, r.x1, r.y1), (2, 3, 10, 7));
        assert_eq!((r.width(), r.height()), (8, 4));
        assert!(r.contains(2, 3) && r.contains(9, 6) && !r.contains(10, 6));
        assert_eq!(r.to_string(), "2,3,10,7");
        assert_eq!(Region::parse("0,0,16,9", 16, 9), Ok(Region::full(16, 9)));
        for (bad, says) in [
            ("1,2,3", "is not x0,y0,x1,y1"),
            ("1,2,3,x", "is not x0,y0,x1,y1"),
            ("-1,2,3,4", "is not x0,y0,x1,y1"),
            ("4,2,4,5", "is empty"),
            ("1,5,3,2", "is empty"),
            ("0,0,17,9", "outside the 16×9 frame"),
            ("0,0,16,10", "outside the 16×9 frame"),
        ] {
            let e = Region::parse(bad, 16, 9).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
        let a = Region::parse("0,0,8,8", 16, 16).unwrap();
        let b = Region::parse("4,6,12,16", 16, 16).unwrap();
        assert_eq!(
            a.intersect(&b),
            Some(Region::parse("4,6,8,8", 16, 16).unwrap())
        );
        assert_eq!(
            a.intersect(&Region::parse("8,0,9,1", 16, 16).unwrap()),
            None
        );
    }
}
