//! Phase functions: how much light a cloud droplet scatters into each direction.
//!
//! In: the cosine `μ` between the light's travel direction and the scattered direction, and the
//! asymmetry `g`. Out: the phase function's value per steradian (each integrates to 1 over the
//! sphere). Used by the shader (`light/shading.rs`) for the sun and the octaves, and by the sky
//! cells (`light/sky_cells.rs`).
//!
//! Sampling it (the reference path tracer's and the fluence estimate's scattering):
//! [`sample_cloud_phase`].
//!
//! - Henyey & Greenstein (1941), "Diffuse radiation in the galaxy", ApJ 93: the phase function.

use std::f32::consts::PI;

use glam::Vec3A;

/// Henyey–Greenstein phase function `(1 − g²) / (4π (1 + g² − 2gμ)^{3/2})` for the cosine `μ`
/// between the light's travel direction and the scattered direction. Integrates to 1 over the
/// sphere for any `g ∈ (−1, 1)`.
#[inline]
pub fn henyey_greenstein(mu: f32, g: f32) -> f32 {
    let g2 = g * g;
    let d = (1.0 + g2 - 2.0 * g * mu).max(1e-6);
    (1.0 - g2) / (4.0 * PI * d * d.sqrt())
}

/// Weight of the backward lobe in [`cloud_phase`].
pub const BACK_LOBE_WEIGHT: f32 = 0.2;
/// Asymmetry of the backward lobe relative to the scene's `g`.
pub const BACK_LOBE_RATIO: f32 = -0.4;

/// The cloud's two-lobe phase function: `(1 − w)·HG(μ, g) + w·HG(μ, −0.4 g)` with
/// `w =` [`BACK_LOBE_WEIGHT`]; the back lobe brightens the side facing the sun, as Mie
/// scattering by droplets does. Integrates to 1.
#[inline]
pub fn cloud_phase(mu: f32, g: f32) -> f32 {
    (1.0 - BACK_LOBE_WEIGHT) * henyey_greenstein(mu, g)
        + BACK_LOBE_WEIGHT * henyey_greenstein(mu, BACK_LOBE_RATIO * g)
}

/// The share of [`cloud_phase`] (asymmetry `g`) scattered within the cone of directions whose
/// cosine to the forward direction is at least `mu0`: each lobe's distribution in `μ` in
/// closed form, `(1 − g²)/(2g) · (1/(1 − g) − 1/√(1 + g² − 2gμ₀))` (`(1 − μ₀)/2` at `g` 0).
pub(crate) fn cloud_phase_within(mu0: f32, g: f32) -> f32 {
    let lobe = |g: f32| {
        if g.abs() < 1e-4 {
            0.5 * (1.0 - mu0)
        } else {
            (1.0 - g * g) / (2.0 * g)
                * (1.0 / (1.0 - g) - 1.0 / (1.0 + g * g - 2.0 * g * mu0).sqrt())
        }
    };
    (1.0 - BACK_LOBE_WEIGHT) * lobe(g) + BACK_LOBE_WEIGHT * lobe(BACK_LOBE_RATIO * g)
}

/// The cosine `μ` of a Henyey–Greenstein lobe of asymmetry `g` for a uniform `ξ` (the inverse
/// of its distribution in `μ`, pbrt's form; exact).
#[inline]
pub(crate) fn sample_hg_cos(g: f32, xi: f32) -> f32 {
    if g.abs() < 1e-3 {
        return 1.0 - 2.0 * xi;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// A travel direction scattered from unit `d` by [`cloud_phase`] with asymmetry `g`, sampled
/// exactly from three uniforms `[pick, ξ, v]` (the lobe by its weight, its cosine, the
/// azimuth), and its cosine `μ` to `d` (the density is `cloud_phase(μ, g)`).
#[inline]
pub(crate) fn sample_cloud_phase(d: Vec3A, g: f32, [pick, xi, v]: [f32; 3]) -> (Vec3A, f32) {
    let lobe = if pick < BACK_LOBE_WEIGHT {
        BACK_LOBE_RATIO * g
    } else {
        g
    };
    let mu = sample_hg_cos(lobe, xi);
    let s = (1.0 - mu * mu).max(0.0).sqrt();
    let phi = 2.0 * PI * v;
    let (t, b) = basis(d);
    let dir = (t * (s * phi.cos()) + b * (s * phi.sin()) + d * mu).normalize();
    (dir, mu)
}

/// Two unit vectors completing unit `n` to an orthonormal basis (Duff et al. 2017).
#[inline]
pub(crate) fn basis(n: Vec3A) -> (Vec3A, Vec3A) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3A::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3A::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ p dω over the sphere by the midpoint rule in μ (the azimuth integral is 2π).
    fn integrate(p: impl Fn(f32) -> f32) -> f64 {
        let n = 200_000;
        (0..n)
            .map(|i| {
                let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                p(mu as f32) as f64 * 2.0 / n as f64
            })
            .sum::<f64>()
            * 2.0
            * std::f64::consts::PI
    }

    #[test]
    fn phase_functions_integrate_to_one() {
        for g in [-0.5, 0.0, 0.3, 0.75, 0.9] {
            let hg = integrate(|mu| henyey_greenstein(mu, g));
            assert!((hg - 1.0).abs() < 1e-3, "HG g={g}: {hg}");
            let c = integrate(|mu| cloud_phase(mu, g));
            assert!((c - 1.0).abs() < 1e-3, "cloud g={g}: {c}");
        }
    }

    #[test]
    fn the_share_within_a_cone_matches_a_quadrature() {
        for g in [0.0f32, 0.3, 0.75, 0.9] {
            for deg in [5.0f32, 20.0, 60.0, 180.0] {
                let mu0 = deg.to_radians().cos();
                let q = integrate(|mu| if mu >= mu0 { cloud_phase(mu, g) } else { 0.0 });
                let c = cloud_phase_within(mu0, g) as f64;
                assert!((c - q).abs() < 2e-3, "g {g}, {deg}°: {c} against {q}");
            }
        }
        // The shipped cone holds about a third of the cloud's scattering.
        let c = cloud_phase_within(20f32.to_radians().cos(), 0.75);
        assert!((0.33..0.35).contains(&c), "{c}");
    }

    #[test]
    fn hg_matches_closed_form_values() {
        // g = 0: isotropic 1/4π. Forward peak (1+g)/(4π(1−g)²), backward (1−g)/(4π(1+g)²).
        let inv4pi = 1.0 / (4.0 * PI);
        assert!((henyey_greenstein(0.3, 0.0) - inv4pi).abs() < 1e-7);
        let g = 0.75f32;
        let fwd = (1.0 + g) / (4.0 * PI * (1.0 - g) * (1.0 - g));
        let back = (1.0 - g) / (4.0 * PI * (1.0 + g) * (1.0 + g));
        assert!((henyey_greenstein(1.0, g) / fwd - 1.0).abs() < 1e-5);
        assert!((henyey_greenstein(-1.0, g) / back - 1.0).abs() < 1e-5);
        // Mean cosine equals g.
        let n = 100_000;
        let mean: f64 = (0..n)
            .map(|i| {
                let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                mu * henyey_greenstein(mu as f32, g) as f64 * 2.0 / n as f64
            })
            .sum::<f64>()
            * 2.0
            * std::f64::consts::PI;
        assert!((mean - g as f64).abs() < 1e-3, "mean cosine {mean}");
    }
}
