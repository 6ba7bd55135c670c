use super::*;
use crate::render::light::grid::LightGrid;
use crate::render::light::phase::cloud_phase;
use crate::render::{Homogeneous, Shape};

/// A ball of radius 1 and extinction `sigma` at the origin.
fn ball(sigma: f32) -> Homogeneous {
    Homogeneous {
        shape: Shape::Ball {
            center: Vec3A::ZERO,
            radius: 1.0,
        },
        sigma_t: sigma,
        step: 0.02,
    }
}

/// Sun only (irradiance 1 in every channel), travelling along `sun_dir`.
fn sun_only(sun_dir: Vec3A, albedo: f32, photons: u32) -> FluenceSettings {
    FluenceSettings {
        sun_dir,
        sun: Vec3A::ONE,
        sky: vec![Vec3A::ZERO; SKY_STRATA],
        albedo,
        g: 0.75,
        photons,
        seed: 5,
        contrast: 0.0,
    }
}

fn fluence_of(m: &Homogeneous, s: &FluenceSettings, res: u32) -> FluenceGrid {
    let grid = LightGrid::build_reusing(m, s.sun_dir, res, None, None, Some(s)).expect("a ball");
    grid.fluence.expect("asked for")
}

/// Distance from `y` inside the unit ball to its surface along unit `d`.
fn to_surface(y: Vec3A, d: Vec3A) -> f32 {
    let b = y.dot(d);
    -b + (b * b - (y.length_squared() - 1.0)).max(0.0).sqrt()
}

/// The fluence and flux at `x` of sunlight scattered exactly once in the ball (irradiance 1,
/// extinction `sigma`, albedo `albedo`), by quadrature: over directions `ω` of arrival, the
/// line back from `x` through the ball, each point lit through its own depth toward the sun.
fn first_order(x: Vec3A, sun_dir: Vec3A, sigma: f32, albedo: f32) -> (f32, Vec3A) {
    let (nu, nphi, ns) = (200, 100, 200);
    let (mut phi, mut flux) = (0.0f64, Vec3A::ZERO);
    for i in 0..nu {
        let mu = -1.0 + 2.0 * (i as f32 + 0.5) / nu as f32;
        let r = (1.0 - mu * mu).sqrt();
        for j in 0..nphi {
            let a = 2.0 * std::f32::consts::PI * (j as f32 + 0.5) / nphi as f32;
            // ω: the light's direction of travel at x.
            let w = Vec3A::new(r * a.cos(), mu, r * a.sin());
            let back = to_surface(x, -w);
            let p = cloud_phase(sun_dir.dot(w), 0.75);
            let mut l = 0.0f32;
            let ds = back / ns as f32;
            for k in 0..ns {
                let s = (k as f32 + 0.5) * ds;
                let y = x - w * s;
                let t_sun = (-sigma * to_surface(y, -sun_dir)).exp();
                l += albedo * sigma * p * t_sun * (-sigma * s).exp() * ds;
            }
            let dw = 4.0 * std::f32::consts::PI / (nu * nphi) as f32;
            phi += (l * dw) as f64;
            flux += w * (l * dw);
        }
    }
    (phi as f32, flux)
}

#[test]
fn fluence_in_a_thin_ball_matches_the_first_order_by_quadrature() {
    // At albedo 0.05 the orders beyond the first are under 3 % of it (optical radius 1); the
    // ball's rim on the fluence grid's 40 cells and the smoothing move the first order's
    // fluence by up to about 6 % either way (2²⁰ paths: −5.6 % at the centre, −4.1 % half-way
    // down, −0.6 % half-way up, +4.2 % at the side; at 2¹⁸ the paths' own noise reached 12 %
    // at one point with another seed).
    let (sigma, albedo) = (1.0, 0.05);
    let sun_dir = Vec3A::new(0.3, -1.0, 0.2).normalize();
    let f = fluence_of(&ball(sigma), &sun_only(sun_dir, albedo, 1 << 20), 240);
    for x in [
        Vec3A::ZERO,
        sun_dir * 0.5,
        -sun_dir * 0.5,
        Vec3A::new(0.5, 0.0, 0.0),
    ] {
        let (phi, flux) = first_order(x, sun_dir, sigma, albedo);
        let got = f.lookup(x);
        let rel = got.sun_once / phi - 1.0;
        println!("φ₁ at {x}: {rel:+.3} against the first order");
        assert!(
            (-0.08..0.08).contains(&rel),
            "φ₁ at {x}: {} against the first order {phi} ({rel:+.3})",
            got.sun_once
        );
        // Its flux (the closure's lobe axis and mean cosine, `Shading::fluence_in`) against
        // the first order's by quadrature: 5–9 % off (the same rim and smoothing as φ₁).
        let rel_flux = (got.sun_once_flux - flux).length() / flux.length();
        println!("F₁ at {x}: {rel_flux:.3} off the first order's {flux}");
        assert!(
            rel_flux < 0.15,
            "F₁ at {x}: {} against the first order {flux} ({rel_flux:.3})",
            got.sun_once_flux
        );
        // The higher orders: a few per cent at this albedo, white.
        let rest = got.fluence.x / phi;
        assert!((0.001..0.06).contains(&rest), "orders ≥ 2 at {x}: {rest}");
        assert!((got.fluence.y - got.fluence.x).abs() <= 1e-5 * got.fluence.x);
        // At the centre their flux still flows with the sun's light (forward scattering), as
        // the first order's does (off the axis it flows out of the ball).
        if x == Vec3A::ZERO {
            assert!(got.flux.dot(sun_dir) > 0.0, "flux at {x}: {}", got.flux);
            assert!(flux.dot(sun_dir) > 0.0);
        }
    }
}

#[test]
fn fluence_is_bit_identical_at_any_thread_count() {
    let s = sun_only(Vec3A::new(-0.5, -0.8, 0.1).normalize(), 0.95, 1 << 14);
    let m = ball(8.0);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a pool")
            .install(|| fluence_of(&m, &s, 64).values)
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
    assert!(one.iter().any(|&v| v > 0.0));
}

#[test]
fn a_thick_white_ball_glows_more_than_its_first_order() {
    // Albedo 1, optical radius 10: the light diffuses through; at the centre the orders ≥ 1
    // are far more than the first alone, and the far side is lit (the octaves' failing).
    let sun_dir = Vec3A::NEG_Y;
    let f = fluence_of(&ball(10.0), &sun_only(sun_dir, 1.0, 1 << 16), 64);
    let (first, _) = first_order(Vec3A::ZERO, sun_dir, 10.0, 1.0);
    let all = |x: Vec3A| {
        let m = f.lookup(x);
        m.fluence.x + m.sun_once
    };
    let centre = all(Vec3A::ZERO);
    assert!(
        centre > 3.0 * first,
        "centre {centre} vs first order {first}"
    );
    let far = all(sun_dir * 0.8);
    assert!(far > 0.1 * centre, "far side {far} vs centre {centre}");
    // Flux flows away from the sun at the far side.
    assert!(f.lookup(sun_dir * 0.8).flux.dot(sun_dir) > 0.0);
}

#[test]
fn the_contrast_keeps_the_mean_and_spreads_the_light() {
    let sun_dir = Vec3A::NEG_Y;
    let mut s = sun_only(sun_dir, 0.95, 1 << 15);
    let plain = fluence_of(&ball(10.0), &s, 48);
    s.contrast = 1.0;
    let spread = fluence_of(&ball(10.0), &s, 48);
    let (top, bottom) = (-sun_dir * 0.7, sun_dir * 0.7);
    let all = |g: &FluenceGrid, x: Vec3A| {
        let m = g.lookup(x);
        m.fluence.x + m.sun_once
    };
    let ratio = |g: &FluenceGrid| all(g, top) / all(g, bottom);
    assert!(ratio(&plain) > 1.0);
    // c = 1 squares the ratio of any two nodes.
    let r = ratio(&spread) / ratio(&plain).powi(2);
    assert!((r - 1.0).abs() < 0.25, "{r}");
}

#[test]
fn coarsening_keeps_the_mean_and_fits() {
    let shape = GridShape {
        origin: Vec3A::ZERO,
        h: 0.1,
        dims: [170, 60, 7],
    };
    let sigma: Vec<f32> = (0..shape.len()).map(|i| (i % 13) as f32).collect();
    let (c, v) = coarsen(&shape, &sigma, 80);
    assert_eq!(c.dims, [57, 20, 3]);
    assert!((c.h - 0.3).abs() < 1e-6);
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    assert!((mean(&v) - mean(&sigma)).abs() < 0.1);
}

/// The sun's share of the orders ≥ 2 is all of them when the sky is black, none of them when
/// the sun is; the cells' mean sun detail is the detail's mean over the cell: between the
/// sunlit top and the shaded bottom of a ball it falls as the exact detail does, and at each
/// point it lies within the detail's range over the cell around it.
#[test]
fn the_suns_share_and_its_detail_are_kept_per_cell() {
    let sun_dir = Vec3A::NEG_Y;
    let sigma = 6.0;
    let s = sun_only(sun_dir, 0.95, 1 << 15);
    let f = fluence_of(&ball(sigma), &s, 48);
    for y in [-0.6f32, -0.2, 0.2, 0.6] {
        let m = f.lookup(Vec3A::new(0.1, y, 0.0));
        let phi = luminance(m.fluence);
        assert!(phi > 0.0);
        assert!(
            (m.sun_multiple / phi - 1.0).abs() < 1e-3,
            "y {y}: the sun's share {} of {phi}",
            m.sun_multiple
        );
    }
    let mut sky = sun_only(sun_dir, 0.95, 1 << 15);
    sky.sun = Vec3A::ZERO;
    sky.sky = vec![Vec3A::ONE; SKY_STRATA];
    let g = fluence_of(&ball(sigma), &sky, 48);
    let m = g.lookup(Vec3A::ZERO);
    assert!(luminance(m.fluence) > 0.0 && m.sun_multiple == 0.0);

    // The exact detail at `x`: the sun's depth is σ times the chord up to the surface.
    let exact = |x: Vec3A| sun_detail(exp_neg(sigma * to_surface(x, -sun_dir).max(0.0)));
    // A cell (the ball's box, padded, over at most 40 cells); the mean reaches about 2.5
    // cells (its block, the smoothing, the interpolation).
    let cell = 2.6 / MAX_FLUENCE_CELLS as f32;
    let mut previous = f32::INFINITY;
    for y in [0.8f32, 0.5, 0.2, -0.1, -0.4, -0.7] {
        let x = Vec3A::new(0.05, y, 0.0);
        let mean = f.lookup(x).sun_detail_mean;
        assert!(
            mean < previous,
            "y {y}: the mean detail {mean} does not fall"
        );
        previous = mean;
        let (lo, hi) = (
            exact(x + Vec3A::new(0.0, -3.0 * cell, 0.0)),
            exact(x + Vec3A::new(0.0, 3.0 * cell, 0.0)),
        );
        assert!(
            mean > lo * 0.97 && mean < hi * 1.03,
            "y {y}: mean detail {mean} outside [{lo}, {hi}] (exact here {})",
            exact(x)
        );
    }
}
