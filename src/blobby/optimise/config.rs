//! Settings of the full optimisation: sweeps, constraint points, shape prior, adaptive budget
//! and swap rounds, each with what it measured.

/// Settings of the full optimisation. Offsets are fractions of the diagonal `D`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FullConfig {
    /// Gauss–Seidel sweeps over all blobs.
    pub sweeps: usize,
    /// LM iterations per blob per sweep.
    pub iterations: usize,
    /// Offsets along `−n` of the inside constraint points.
    pub inside_offsets: Vec<f64>,
    /// Offsets along `+n` of the outside constraint points.
    pub outside_offsets: Vec<f64>,
    /// Weight of a sign-constraint residual relative to a surface residual.
    pub constraint_weight: f64,
    /// Field margin `τ`: inside points want `F ≥ τ`, outside points `F ≤ −τ`.
    pub margin: f64,
    /// Use at most this many surface samples (evenly strided) per point kind.
    pub max_points: usize,
    /// Strength of the prior keeping radii and centres near the decomposition, as a length
    /// in units of `D` (see `Sweep::improve`). 0.001: halving the earlier 0.002 (with the
    /// final sweeps) lowered the mean error 8–20 % at 100 and 300 blobs on the bunny, horse and
    /// armadillo; 0.0005 lowered it further but let blob tails overshoot armadillo's extremities
    /// (max 1.5 → 1.9 % of D at 100 blobs).
    pub shape_prior: f64,
    /// Adaptive budget: rounds of adding blobs at the worst shortfalls, up to the blob count
    /// asked for, each followed by `budget_sweeps` sweeps (0 = keep only the surviving blobs).
    pub budget_rounds: usize,
    /// Sweeps after each adaptive-budget round.
    pub budget_sweeps: usize,
    /// Sweeps over every blob after the adaptive budget. 6 against 2: mean −3 to −5 % at 100
    /// blobs on the bunny, horse and armadillo; with `final_shape_prior`, −6 to −11 % at 300.
    pub final_sweeps: usize,
    /// The shape prior of the final sweeps (a continuation: the blobs settle under
    /// `shape_prior`, then refine under this weaker one). 0.0005 throughout let blob tails
    /// overshoot armadillo's extremities (max 1.5 → 1.9 % of D at 100 blobs); 0.0007 in the
    /// final sweeps only lowered the mean 2–7 % at 100 blobs on the bunny, horse and armadillo,
    /// the max moving by −0.15 to +0.11 % of D.
    pub final_shape_prior: f64,
    /// The adaptive budget adds blobs only where the model falls shorter than this. Shallower
    /// gaps are the optimiser's job: blobs added there measured worse (they bulge out
    /// elsewhere), so a model may end with fewer blobs than asked.
    pub budget_shortfall: f64,
    /// Share of the selection held back from the start and left to the adaptive budget, in
    /// models of at most [`FullConfig::reserve_up_to`] blobs: the greedy coverage order spends
    /// its last picks on volume, the budget on where the surface falls short (where it finds
    /// no shortfall deep enough, the model keeps fewer blobs). 0.2 at 100 blobs: mean −5 % on
    /// the bunny (its max 0.84 → 0.95 % of D), armadillo's max 1.58 → 1.34 % of D (with the
    /// final sweeps below, whose weaker prior alone lets it pass 1.5 %).
    pub budget_reserve: f64,
    /// The largest model that holds back [`FullConfig::budget_reserve`] and runs the swap
    /// rounds. At 300 blobs the budget finds few shortfalls deep enough: held back, the bunny
    /// and horse ended with 160–250 blobs and a higher mean (filling from the held-back picks
    /// did not recover it); swap rounds there moved the mean by −5 to +1 % and raised the
    /// bunny's max, at twice the fit time.
    pub reserve_up_to: usize,
    /// Swap rounds after the final sweeps in models of at most [`FullConfig::reserve_up_to`]
    /// blobs: each drops the [`FullConfig::swap_blobs`] blobs whose removal raises the
    /// residual least and adds as many at the worst shortfalls, keeping the round only if the
    /// total residual fell (the first that does not ends them). 6 rounds of 5 at 100 blobs:
    /// mean −15 % on armadillo (0.175 → 0.148 % of D), −6 to −9 % on the bunny and horse, the
    /// max lower on all three; 8 rounds gained 1 % more for a fifth more fit time.
    pub swap_rounds: usize,
    /// Blobs moved per swap round. 3 and 8 measured about as well as 5.
    pub swap_blobs: usize,
    /// Sweeps of a swap round: this many around the moved blobs, then this many over every
    /// blob. 1 instead of 2 kept only half the gain.
    pub swap_sweeps: usize,
}

impl FullConfig {
    /// True when a model of `blobs` blobs is small enough to hold blobs back and run swap
    /// rounds (see [`FullConfig::reserve_up_to`]).
    pub fn is_small(&self, blobs: usize) -> bool {
        blobs <= self.reserve_up_to
    }

    /// How many of `selected` blobs the start holds back for the budget (see
    /// [`FullConfig::budget_reserve`]); at least one blob always starts.
    pub fn held_back(&self, selected: usize) -> usize {
        if !self.is_small(selected) {
            return 0;
        }
        let n = (selected as f64 * self.budget_reserve.clamp(0.0, 1.0)).round() as usize;
        n.min(selected.saturating_sub(1))
    }
}

impl Default for FullConfig {
    fn default() -> Self {
        FullConfig {
            sweeps: 3,
            iterations: 2,
            inside_offsets: vec![0.005, 0.02],
            outside_offsets: vec![0.005, 0.03, 0.1],
            constraint_weight: 0.5,
            margin: 0.05,
            max_points: 12_000,
            shape_prior: 0.001,
            budget_rounds: 3,
            budget_sweeps: 3,
            final_sweeps: 6,
            final_shape_prior: 0.0007,
            budget_shortfall: 0.004,
            budget_reserve: 0.2,
            reserve_up_to: 150,
            swap_rounds: 6,
            swap_blobs: 5,
            swap_sweeps: 2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_small_selections_hold_blobs_back() {
        let cfg = FullConfig::default();
        assert_eq!(cfg.held_back(100), 20);
        assert_eq!(cfg.held_back(cfg.reserve_up_to + 1), 0);
        assert_eq!(cfg.held_back(300), 0);
        assert_eq!(cfg.held_back(0), 0);
        let all = FullConfig {
            budget_reserve: 1.0,
            ..cfg
        };
        assert_eq!(all.held_back(10), 9, "one blob always starts");
    }
}
