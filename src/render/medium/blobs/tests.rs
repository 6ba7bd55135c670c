//! The blob medium's unit tests: the march step, the light grid's cells, the density under
//! many overlaps, and the gather's caches against the plain computation.
use super::gather::{GatherBuffers, HitSort, all_of};
use super::*;
use crate::render::camera::Ray;
use crate::render::medium::Medium;
use crate::render::medium::density::{Hit, MAX_ACTIVE, density};

/// An 8×8 `Final` frame looking down +Z from z = −5, with length unit `length_scale`.
fn tiny_settings(length_scale: f32) -> RenderSettings {
    use crate::render::Camera;
    use crate::render::settings::{CloudMaterial, Quality, Sky, Sun};
    RenderSettings {
        width: 8,
        height: 8,
        camera: Camera {
            position: glam::Vec3::new(0.0, 0.0, -5.0),
            look_at: glam::Vec3::ZERO,
            up: glam::Vec3::Y,
            fov_deg: 40.0,
            shift: glam::Vec2::ZERO,
        },
        sun: Sun::default(),
        sky: Sky::default(),
        cloud: CloudMaterial::default(),
        exposure: 0.0,
        length_scale,
        seed: 1,
        time: 0.0,
        quality: Quality::final_frame(),
        base: None,
        surfaces: None,
    }
}

#[test]
fn blobs_being_born_do_not_set_the_march_step() {
    use glam::{DQuat, DVec3};
    let s = tiny_settings(10.0);
    let blob = |x: f64, r: f64| Blob {
        center: DVec3::new(x, 0.0, 0.0),
        rotation: DQuat::IDENTITY,
        semi_axes: DVec3::splat(r),
        a: 1.0,
        b: 2.0,
    };
    let grown: Vec<Blob> = (0..6).map(|i| blob(i as f64, 0.4)).collect();
    let step = BlobMedium::new(&s, &grown).step();
    // 46 specks (1/500 of the grown ones) beside them: the step is the grown blobs' ...
    let mut born = grown.clone();
    born.extend((0..46).map(|i| blob(0.01 * i as f64, 0.0008)));
    assert_eq!(BlobMedium::new(&s, &born).step(), step);
    // ... while 46 blobs a quarter of their size do set it (the median is theirs).
    let mut small = grown.clone();
    small.extend((0..46).map(|i| blob(0.01 * i as f64, 0.1)));
    let small_step = BlobMedium::new(&s, &small).step();
    assert!(small_step < 0.3 * step, "{small_step} vs {step}");
}

#[test]
fn light_grid_cells_are_no_finer_than_a_pixel() {
    use crate::render::MIN_LIGHT_GRID_CELLS;
    let mut s = tiny_settings(1.0);
    s.height = 360;
    let px = s.pixel_footprint();
    let box_of = |pixels: f32| Some((Vec3A::ZERO, Vec3A::new(pixels * px, 1e-3, 1e-3)));
    // A cloud 100 px across gets 100 cells, one 1,000 px across the quality's 224, one 5 px
    // across the floor; no pixel floor (0) or no bounds: the quality's.
    assert_eq!(s.light_grid_cells(box_of(100.0)), 100);
    assert_eq!(s.light_grid_cells(box_of(1000.0)), 224);
    assert_eq!(s.light_grid_cells(box_of(5.0)), MIN_LIGHT_GRID_CELLS);
    assert_eq!(s.light_grid_cells(None), 224);
    s.quality.shadow_cell_pixels = 0.5;
    assert_eq!(s.light_grid_cells(box_of(100.0)), 200);
    s.quality.shadow_cell_pixels = 0.0;
    assert_eq!(s.light_grid_cells(box_of(5.0)), 224);
}

#[test]
fn density_is_finite_under_more_overlapping_blobs_than_the_active_list_holds() {
    use glam::{DQuat, DVec3};
    // 30 weak, wide blobs whose supports the ray enters first, then one strong blob: the
    // strong one must make the active list (it used to be left out, giving 0/0 = NaN).
    let sphere = |z: f64, r: f64, b: f64| Blob {
        center: DVec3::new(0.0, 0.0, z),
        rotation: DQuat::IDENTITY,
        semi_axes: DVec3::splat(r),
        a: 1.0,
        b,
    };
    let mut blobs: Vec<Blob> = (0..30)
        .map(|i| sphere(0.01 * i as f64, 1.0, 0.05))
        .collect();
    blobs.push(sphere(0.0, 0.3, 4.0));
    let settings = tiny_settings(2.0);
    let m = BlobMedium::new(&settings, &blobs);
    let ray = Ray {
        origin: Vec3A::new(0.0, 0.0, -5.0),
        dir: Vec3A::Z,
    };
    let (mut hits, mut ivs) = (Vec::new(), Vec::new());
    let all: Vec<u32> = (0..m.len() as u32).collect();
    m.gather(
        &all,
        &ray,
        0.0,
        &mut GatherBuffers::default(),
        &mut hits,
        &mut ivs,
    );
    assert!(hits.len() > MAX_ACTIVE);
    let sigma = m.density(&hits, 5.0);
    assert!(
        sigma.is_finite() && sigma > 0.5 * m.params.sigma,
        "σ_t = {sigma}"
    );
}

#[test]
fn origin_cache_gives_each_rays_own_bits() {
    use glam::{DQuat, DVec3};
    let blobs: Vec<Blob> = (0..9)
        .map(|i| Blob {
            center: DVec3::new(0.1 * i as f64, -0.07 * (i % 4) as f64, 0.2 * i as f64),
            rotation: DQuat::from_rotation_x(0.4 * i as f64),
            semi_axes: DVec3::new(0.5, 0.35, 0.25),
            a: 1.0,
            b: 2.0,
        })
        .collect();
    let m = BlobMedium::new(&tiny_settings(4.0), &blobs);
    let all: Vec<u32> = (0..m.len() as u32).collect();
    let eye = Vec3A::new(0.1, 0.0, -3.0);
    let ray = |origin: Vec3A, k: f32| Ray {
        origin,
        dir: Vec3A::new(0.02 * k, 0.01 * k, 1.0).normalize(),
    };
    let gather = |buffers: &mut GatherBuffers, r: &Ray| {
        let (mut hits, mut ivs) = (Vec::new(), Vec::new());
        m.gather(&all, r, 0.0, buffers, &mut hits, &mut ivs);
        format!("{hits:?} {ivs:?}")
    };
    // A cache filled by the tile's first ray, reused by the next rays from the same eye and
    // bypassed by a ray from elsewhere: each gives what a fresh gather gives.
    let mut cache = GatherBuffers::default();
    for (origin, k) in [(eye, 0.0), (eye, 3.0), (eye + Vec3A::X, 1.0), (eye, -2.0)] {
        let r = ray(origin, k);
        let alone = gather(&mut GatherBuffers::default(), &r);
        assert!(alone.contains("Hit"), "the ray should cross blobs");
        assert_eq!(gather(&mut cache, &r), alone);
    }
    assert_eq!(cache.origin.origin, Some(eye));
}

#[test]
fn active_window_gives_the_full_lists_bits() {
    use glam::{DQuat, DVec3};
    // Overlapping blobs along the ray, some ending early: samples at increasing t (and
    // steps back, as the march's re-march takes) through the window equal the full list's.
    let blobs: Vec<Blob> = (0..12)
        .map(|i| Blob {
            center: DVec3::new(0.05 * i as f64, 0.02 * (i % 3) as f64, 0.3 * i as f64),
            rotation: DQuat::from_rotation_y(0.3 * i as f64),
            semi_axes: DVec3::new(0.4, 0.3, 0.2 + 0.05 * (i % 4) as f64),
            a: 1.0,
            b: 2.0,
        })
        .collect();
    let settings = tiny_settings(4.0);
    let m = BlobMedium::new(&settings, &blobs);
    let ray = Ray {
        origin: Vec3A::new(0.0, 0.0, -1.0),
        dir: Vec3A::Z,
    };
    let mut s = m.scratch();
    let all: Vec<u32> = (0..m.len() as u32).collect();
    s.tile = all;
    m.begin_ray(&ray, &mut s);
    let full = s.hits.clone();
    let mut positive = 0;
    for t in (0..400)
        .map(|k| 0.013 * k as f32)
        .chain([0.5, 0.7, 2.0, 1.0, 3.0])
    {
        let window = m.sample(&mut s, t, ray.at(t));
        let exact = density(&m.params, &full, &all_of(&full), t);
        assert_eq!(window.0.to_bits(), exact.0.to_bits(), "t = {t}");
        assert_eq!(window.1, exact.1);
        positive += (exact.0 > 0.0) as u32;
    }
    assert!(positive > 50, "the ray crosses the cloud ({positive})");
}

#[test]
fn hit_sort_orders_by_entry_and_keeps_ties_in_gathering_order() {
    let hit = |t0: f32, blob: u32| {
        Hit::new(
            blob,
            (t0, t0.abs() + 1.0),
            1.0,
            0.0,
            0.0,
            glam::Mat3A::IDENTITY,
            (Vec3A::ZERO, Vec3A::X),
            (Vec3A::ZERO, Vec3A::ZERO),
        )
    };
    let mut sort = HitSort::default();
    let mut rng = 0x2545_f491_u32;
    for n in [0usize, 1, 2, 7, 40] {
        let mut hits: Vec<Hit> = (0..n as u32)
            .map(|k| {
                rng = rng.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                // Few distinct entries (ties), both zeros, a negative.
                let t0 = [0.0, -0.0, 0.5, 0.25, 3.0, -1.0][(rng >> 28) as usize % 6];
                hit(t0, k)
            })
            .collect();
        let mut expected = hits.clone();
        expected.sort_by(|a, b| a.t0.total_cmp(&b.t0));
        sort.sort(&mut hits);
        let key = |h: &Hit| (h.t0.to_bits(), h.blob);
        assert_eq!(
            hits.iter().map(key).collect::<Vec<_>>(),
            expected.iter().map(key).collect::<Vec<_>>(),
            "{n} hits"
        );
    }
}

#[test]
fn a_hit_is_112_bytes() {
    // The gather copies each hit once into its sorted place and the density walks them
    // sample by sample: their size is what the comments in `gather` quote.
    assert_eq!(std::mem::size_of::<Hit>(), 112);
}
