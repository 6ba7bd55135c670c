//! The render benchmark (an ignored unit test: it reads the renderer's internals, the work
//! counters and the sun's columns): per frame of the 400-blob test cloud
//! ([`crate::render::fixture`]), the median time of the whole frame and of its parts, the bytes
//! allocated, the light grid's nodes, and with the `counters` feature the frame's work.
//!
//! `cargo test --release --lib -- --ignored --nocapture render::bench` (add `--features
//! counters` for the work counters; docs/SPEED.md).

use glam::Vec3A;

use crate::blobby::Blob;
use crate::render::counters::{self, Counter};
use crate::render::fixture::{settings, test_cloud, time};
use crate::render::light::sun_depth::SunGrid;
use crate::render::{
    BlobMedium, Film, LightGrid, Quality, RenderSettings, render_frame, render_medium,
    render_medium_unshaded,
};

/// The system allocator, counting the bytes allocated (for the benchmark's "bytes allocated").
struct CountingAlloc;

static ALLOCATED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

unsafe impl std::alloc::GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        ALLOCATED.fetch_add(layout.size() as u64, std::sync::atomic::Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        ALLOCATED.fetch_add(layout.size() as u64, std::sync::atomic::Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { std::alloc::System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new: usize) -> *mut u8 {
        ALLOCATED.fetch_add(new as u64, std::sync::atomic::Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { std::alloc::System.realloc(ptr, layout, new) }
    }
}

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

/// Bytes allocated while `f` runs (by any thread).
fn allocated<T>(f: impl FnOnce() -> T) -> (T, u64) {
    let before = ALLOCATED.load(std::sync::atomic::Ordering::Relaxed);
    let out = f();
    (
        out,
        ALLOCATED.load(std::sync::atomic::Ordering::Relaxed) - before,
    )
}

/// One frame's work counters, printed per frame.
fn print_work(s: &RenderSettings, blobs: &[Blob]) {
    let m = BlobMedium::new(s, blobs);
    // The light grid samples the medium without the billows it cannot hold, as a frame's does.
    let lattice = m.for_light_grid(s);
    counters::take();
    let (grid, grid_bytes) = allocated(|| LightGrid::for_frame(s, &lattice));
    let light = counters::take();
    let (_, march_bytes) = allocated(|| render_medium(s, &m, &grid, &Film::default()));
    let march = counters::take();
    let size = grid.as_ref().map(|g| g.size());
    let sun_dir = Vec3A::from(s.sun.travel_dir());
    let h = size.map_or(1.0, |_| {
        let (lo, hi) = m.bounds().unwrap();
        (hi - lo).max_element() / s.light_grid_cells(Some((lo, hi))) as f32
    });
    let sun_s = median(
        (0..3)
            .map(|_| time(|| SunGrid::build(&lattice, sun_dir, h, None)).1)
            .collect(),
    );
    println!("  of which the sun's columns {sun_s:.3} s");
    let m = |x: u64| x as f64 / 1e6;
    println!(
        "  light grid: {:.2} M world nodes, {:.2} M sun nodes, {:.2} M sky nodes ({:.0} MB kept); {:.0} MB allocated building it, {:.0} MB marching",
        m(size.map_or(0, |z| z.world) as u64),
        m(size.map_or(0, |z| z.sun) as u64),
        m(size.map_or(0, |z| z.sky) as u64),
        m(size.map_or(0, |z| z.bytes) as u64),
        m(grid_bytes),
        m(march_bytes),
    );
    if !counters::ENABLED {
        println!("  (work counters: build with --features counters)");
        return;
    }
    for (part, c) in [("light grid", light), ("march", march)] {
        let n = |k: Counter| c[k as usize];
        let samples = n(Counter::MarchSamples) + n(Counter::LightSamples);
        println!(
            "  {part}: {:.2} M density samples, {:.2} hits visited a sample, {:.2} M noise stacks ({:.2} M octaves), {:.2} M shaded samples, {:.2} M fine samples that found nothing in the billows' band, {:.2} M fine samples beyond their reach, {:.2} M coarse samples",
            m(samples),
            n(Counter::HitsVisited) as f64 / samples.max(1) as f64,
            m(n(Counter::NoiseEvals)),
            m(n(Counter::NoiseOctaves)),
            m(n(Counter::ShadedSamples)),
            m(n(Counter::EmptyFine)),
            m(n(Counter::FineOutside)),
            m(n(Counter::CoarseSamples)),
        );
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
#[ignore = "benchmark: run in release with --ignored --nocapture"]
fn bench_frame_times() {
    let blobs = test_cloud(400, 11);
    for (name, s, runs) in [
        (
            "640x360 final",
            settings(640, 360, Quality::final_frame()),
            5,
        ),
        ("256x256 preview", settings(256, 256, Quality::preview()), 9),
    ] {
        let total = median(
            (0..runs)
                .map(|_| time(|| render_frame(&s, &blobs)).1)
                .collect(),
        );
        let prep = median(
            (0..runs)
                .map(|_| time(|| BlobMedium::new(&s, &blobs)).1)
                .collect(),
        );
        let m = BlobMedium::new(&s, &blobs);
        let lattice = m.for_light_grid(&s);
        let light = median(
            (0..runs)
                .map(|_| time(|| LightGrid::for_frame(&s, &lattice)).1)
                .collect(),
        );
        let grid = LightGrid::for_frame(&s, &lattice);
        let march = median(
            (0..runs)
                .map(|_| time(|| render_medium(&s, &m, &grid, &Film::default())).1)
                .collect(),
        );
        let dens = median(
            (0..runs)
                .map(|_| time(|| render_medium_unshaded(&s, &m)).1)
                .collect(),
        );
        println!(
            "{name}: median {total:.3} s/frame = prepare {prep:.3} + light grid {light:.3} + march/density {dens:.3} + shading {:.3} (parts timed separately)",
            march - dens,
        );
        print_work(&s, &blobs);
    }
}
