//! Traffic signals: light states, phases and the signal plan.

/// A traffic light state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Light {
    /// Go.
    Green,
    /// Stop if you can (pedestrians: do not start crossing).
    Yellow,
    /// Stop.
    Red,
}

/// One phase of a fixed-time plan: the signal groups that are green.
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    /// Groups green in this phase.
    pub groups: Vec<u8>,
    /// Green time, s.
    pub green_s: f64,
    /// Yellow time, s.
    pub yellow_s: f64,
    /// All-red time after the yellow, s.
    pub all_red_s: f64,
}

/// A fixed-time signal plan that cycles through its phases.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalPlan {
    /// Phases in order.
    pub phases: Vec<Phase>,
    /// Time into the cycle at `t = 0`, s (drawn from the seed).
    pub offset_s: f64,
}

impl SignalPlan {
    /// Cycle length, s.
    pub fn cycle_s(&self) -> f64 {
        self.phases
            .iter()
            .map(|p| p.green_s + p.yellow_s + p.all_red_s)
            .sum()
    }

    /// The light of `group` at time `t_s`.
    pub fn light(&self, group: u8, t_s: f64) -> Light {
        let cycle = self.cycle_s();
        if cycle <= 0.0 {
            return Light::Green;
        }
        let mut t = (t_s + self.offset_s).rem_euclid(cycle);
        for p in &self.phases {
            let len = p.green_s + p.yellow_s + p.all_red_s;
            if t < len {
                if !p.groups.contains(&group) {
                    return Light::Red;
                }
                return if t < p.green_s {
                    Light::Green
                } else if t < p.green_s + p.yellow_s {
                    Light::Yellow
                } else {
                    Light::Red
                };
            }
            t -= len;
        }
        Light::Red
    }
}
