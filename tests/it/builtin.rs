//! Builtin shapes: closed, outward, valid, analytic volumes, fast.

use crate::mesh_checks;

use std::f64::consts::PI;
use std::path::Path;
use std::time::Instant;

use glam::{DMat3, DVec3};
use mesh_checks::{assert_closed_oriented, components, euler_characteristic, min_relative_area};
use nephele::mesh::builtin::{ELLIPSOID_SEMI_AXES, NAMES, builtin};
use nephele::mesh::{Mesh, MeshError};

#[test]
fn every_builtin_is_closed_outward_valid_and_about_two_units() {
    for &name in NAMES {
        let start = Instant::now();
        let mesh = builtin(name).unwrap();
        let secs = start.elapsed().as_secs_f64();
        let size = mesh.bounds().size();
        println!(
            "{name}: {} vertices, {} triangles, size {size:.2}, volume {:.4}, {secs:.3} s",
            mesh.positions.len(),
            mesh.triangles.len(),
            mesh.signed_volume()
        );
        mesh.validate(Path::new(name)).unwrap();
        assert_closed_oriented(&mesh, name);
        assert_eq!(components(&mesh), 1, "{name}: one piece");
        let genus_expected = if name == "torus-knot" { 0 } else { 2 };
        assert_eq!(
            euler_characteristic(&mesh),
            genus_expected,
            "{name}: topology"
        );
        assert!(
            min_relative_area(&mesh) > 1e-6,
            "{name}: degenerate triangle"
        );
        let longest = size.max_element();
        assert!(
            (1.6..=3.1).contains(&longest),
            "{name}: longest side {longest}"
        );
        assert!(mesh.bounds().center().length() < 0.35, "{name}: off-centre");
        assert!(mesh.triangles.len() <= 40_000, "{name}: too heavy");
    }
}

#[test]
fn analytic_volumes() {
    let sphere = builtin("sphere").unwrap();
    let v = sphere.signed_volume();
    assert!(
        (v / (4.0 / 3.0 * PI) - 1.0).abs() < 0.01,
        "sphere volume {v}"
    );
    for p in &sphere.positions {
        assert!((p.length() - 1.0).abs() < 1e-12);
    }
    let e = builtin("ellipsoid").unwrap();
    let s = ELLIPSOID_SEMI_AXES;
    let expect = 4.0 / 3.0 * PI * s.x * s.y * s.z;
    let v = e.signed_volume();
    assert!(
        (v / expect - 1.0).abs() < 0.01,
        "ellipsoid volume {v} vs {expect}"
    );
    // Tube around a closed curve: volume = π r² · length (Pappus), curve length of the
    // scaled trefoil computed numerically.
    let knot = builtin("torus-knot").unwrap();
    let n = 20_000;
    let c = |t: f64| {
        let r = 2.0 + (3.0 * t).cos();
        DVec3::new(r * (2.0 * t).cos(), r * (2.0 * t).sin(), (3.0 * t).sin()) / 3.0
    };
    let len: f64 = (0..n)
        .map(|i| {
            let t = |k: usize| 2.0 * PI * k as f64 / n as f64;
            c(t(i)).distance(c(t(i + 1)))
        })
        .sum();
    let expect = PI * 0.13 * 0.13 * len;
    let v = knot.signed_volume();
    assert!(
        (v / expect - 1.0).abs() < 0.02,
        "knot volume {v} vs {expect}"
    );
}

#[test]
fn unknown_name_lists_the_known_ones() {
    let err = builtin("teapot").unwrap_err();
    assert!(matches!(err, MeshError::UnknownBuiltin { .. }));
    let msg = err.to_string();
    assert!(msg.contains("teapot"), "{msg}");
    for name in NAMES {
        assert!(msg.contains(name), "{msg}");
    }
    let loaded = nephele::mesh::load("builtin:duck").unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
}

#[test]
fn builtins_are_deterministic() {
    for &name in NAMES {
        assert!(builtin(name).unwrap() == builtin(name).unwrap(), "{name}");
    }
}

/// Orthographic z-buffered Lambert render of `mesh` seen from `yaw` (radians about +Y) and a
/// slight downward pitch, into a `size`² RGB tile.
fn render_view(mesh: &Mesh, yaw: f64, pitch: f64, size: u32, color: [f64; 3]) -> image::RgbImage {
    let rot = DMat3::from_rotation_x(pitch) * DMat3::from_rotation_y(yaw);
    let pts: Vec<DVec3> = mesh.positions.iter().map(|&p| rot * p).collect();
    let scale = size as f64 / 2.6;
    let to_px = |p: DVec3| {
        (
            p.x * scale + size as f64 / 2.0,
            size as f64 / 2.0 - p.y * scale,
        )
    };
    let mut depth = vec![f64::NEG_INFINITY; (size * size) as usize];
    let mut img = image::RgbImage::from_pixel(size, size, image::Rgb([40, 50, 70]));
    let light = DVec3::new(-0.4, 0.7, 0.6).normalize();
    for &[a, b, c] in &mesh.triangles {
        let (pa, pb, pc) = (pts[a as usize], pts[b as usize], pts[c as usize]);
        let n = (pb - pa).cross(pc - pa).normalize_or_zero();
        if n.z <= 0.0 {
            continue; // back face (camera looks along −Z)
        }
        let shade = 0.15 + 0.85 * n.dot(light).max(0.0);
        let [(ax, ay), (bx, by), (cx, cy)] = [to_px(pa), to_px(pb), to_px(pc)];
        let area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
        if area.abs() < 1e-12 {
            continue;
        }
        let x0 = ax.min(bx).min(cx).floor().max(0.0) as u32;
        let x1 = (ax.max(bx).max(cx).ceil() as u32).min(size - 1);
        let y0 = ay.min(by).min(cy).floor().max(0.0) as u32;
        let y1 = (ay.max(by).max(cy).ceil() as u32).min(size - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let w0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) / area;
                let w1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * pa.z + w1 * pb.z + w2 * pc.z;
                let k = (y * size + x) as usize;
                if z > depth[k] {
                    depth[k] = z;
                    let px = color.map(|c| (255.0 * c * shade).clamp(0.0, 255.0) as u8);
                    img.put_pixel(x, y, image::Rgb(px));
                }
            }
        }
    }
    img
}

/// Sanity pictures of the figures in /tmp (side, three-quarter, front, back): run with
/// `cargo test --release --test it -- --ignored builtin::`.
#[test]
#[ignore]
fn render_figures_to_tmp() {
    for (name, color) in [
        ("duck", [1.0, 0.85, 0.2]),
        ("bunny-toy", [0.9, 0.9, 0.9]),
        ("torus-knot", [0.6, 0.8, 1.0]),
    ] {
        let mesh = builtin(name).unwrap();
        let tile = 320;
        let views = [0.0, -0.8, -PI / 2.0, PI];
        let mut sheet = image::RgbImage::new(tile * views.len() as u32, tile);
        for (i, &yaw) in views.iter().enumerate() {
            let view = render_view(&mesh, yaw, 0.25, tile, color);
            image::imageops::replace(&mut sheet, &view, (i as u32 * tile) as i64, 0);
        }
        let path = format!("/tmp/nephele_{name}.png");
        sheet.save(&path).unwrap();
        println!("wrote {path}");
    }
}
