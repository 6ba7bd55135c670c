//! Work counters for the benchmark: how many density samples, blob visits, noise evaluations
//! and shaded samples a frame costs, so that speed work is chosen by what the frame does, not
//! guessed.
//!
//! Compiled in only with the `counters` feature (`cargo test --release --features counters
//! --lib -- --ignored --nocapture render::bench`); without it [`add`] is empty and inlines to
//! nothing. The counts are global relaxed atomics: exact totals at any thread count, at a cost
//! that matters only in the counting build (whose times are not the benchmark's).

/// What is counted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(usize)]
pub(crate) enum Counter {
    /// Density evaluations by the camera march.
    MarchSamples,
    /// Density evaluations while filling the light grid.
    LightSamples,
    /// Blob hits whose span starts before the sample (what the density loop walks over).
    HitsVisited,
    /// Erosion noise stacks evaluated (each one `noise.octaves` octaves).
    NoiseEvals,
    /// March samples shaded (a light lookup and the in-scattering).
    ShadedSamples,
    /// Billow octaves evaluated (one gradient noise each, per blob of the blend).
    NoiseOctaves,
    /// March samples inside the medium's shape (fine steps) that found no extinction.
    EmptyFine,
    /// Fine march samples beyond the billows' reach (no noise evaluated): the re-march from the
    /// last empty sample after a coarse one found the cloud, and the tail after leaving it.
    FineOutside,
    /// Coarse march samples (through the blob supports' empty parts, and the one that finds
    /// the cloud and is discarded for the re-march).
    CoarseSamples,
}

/// Number of [`Counter`]s.
#[cfg(any(test, feature = "counters"))]
pub(crate) const COUNTERS: usize = 9;

#[cfg(feature = "counters")]
static COUNTS: [std::sync::atomic::AtomicU64; COUNTERS] =
    [const { std::sync::atomic::AtomicU64::new(0) }; COUNTERS];

/// Add `n` to `counter` (nothing without the `counters` feature).
#[inline(always)]
pub(crate) fn add(counter: Counter, n: u64) {
    #[cfg(feature = "counters")]
    COUNTS[counter as usize].fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    #[cfg(not(feature = "counters"))]
    let _ = (counter, n);
}

/// True when the counters are compiled in.
pub(crate) const ENABLED: bool = cfg!(feature = "counters");

/// The counts since the last call, in [`Counter`] order, and reset them (all 0 without the
/// feature). Read by the benchmark and [`work_counts`].
#[cfg(any(test, feature = "counters"))]
pub(crate) fn take() -> [u64; COUNTERS] {
    #[cfg(feature = "counters")]
    {
        std::array::from_fn(|i| COUNTS[i].swap(0, std::sync::atomic::Ordering::Relaxed))
    }
    #[cfg(not(feature = "counters"))]
    {
        [0; COUNTERS]
    }
}

/// The work counts since the last call (or since the process started), by name, and reset them:
/// what `nephele render --timings` prints in a `--features counters` build. Empty without the
/// feature.
pub fn work_counts() -> Vec<(&'static str, u64)> {
    #[cfg(feature = "counters")]
    {
        const NAMES: [&str; COUNTERS] = [
            "march samples",
            "light-grid samples",
            "hits visited",
            "noise stacks",
            "shaded samples",
            "noise octaves",
            "empty fine samples",
            "fine samples beyond the billows",
            "coarse samples",
        ];
        NAMES.into_iter().zip(take()).collect()
    }
    #[cfg(not(feature = "counters"))]
    {
        Vec::new()
    }
}
