//! The state the relaxation works on: the label probabilities of one direction (made by
//! [`super::initial`], iterated by [`super::update`], read by [`super::decision`]) and a
//! solve's result.

/// The label probabilities of one direction: `real[e]` for every real label (rows of the
/// [`LabelGraph`]) and `none[i]` for every vehicle's no-match label.
#[derive(Debug, Clone, PartialEq)]
pub struct Probabilities {
    /// Probability of each real label.
    pub real: Vec<f64>,
    /// Probability of each vehicle's no-match label.
    pub none: Vec<f64>,
}

/// Probabilities after the iterations, with how they ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Forward probabilities `P`.
    pub p: Probabilities,
    /// Backward probabilities `Q` (bidirectional variants only).
    pub q: Option<Probabilities>,
    /// Iterations run.
    pub iterations: u32,
    /// Whether the last iteration changed no probability by more than `epsilon`.
    pub converged: bool,
    /// Largest change of any probability in the last iteration (0 before any).
    pub last_change: f64,
}
