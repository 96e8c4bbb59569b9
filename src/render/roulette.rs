//! Russian roulette, one rule for every path loop (Mitsuba's): a path survives with
//! probability `q = min(max(beta) eta^2, 0.95)` and is then divided by `q`. Where in
//! the loop it runs and from which depth is each loop's own (`tracer.rs`, `nlos/`).

/// The survival probability of a path of throughput maximum `beta_max` that has
/// crossed relative IORs multiplying to `eta`. Never NaN (`min` drops a NaN product).
#[inline(always)]
pub fn survival(beta_max: f32, eta: f32) -> f32 {
    (beta_max * eta * eta).min(0.95)
}

/// The roulette with uniform `u`: `Some(q)`, the divisor, when the path survives.
#[inline(always)]
pub fn roulette(beta_max: f32, eta: f32, u: f32) -> Option<f32> {
    let q = survival(beta_max, eta);
    if u >= q {
        None
    } else {
        Some(q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn survival_is_capped_and_scales_with_eta_squared() {
        assert_eq!(survival(0.5, 1.0), 0.5);
        assert_eq!(survival(0.5, 2.0), 0.95);
        assert_eq!(survival(0.1, 1.5), 0.1 * 1.5 * 1.5);
        assert_eq!(survival(f32::NAN, 1.0), 0.95);
    }

    #[test]
    fn the_path_survives_below_q_and_dies_at_or_above_it() {
        assert_eq!(roulette(0.5, 1.0, 0.49), Some(0.5));
        assert_eq!(roulette(0.5, 1.0, 0.5), None);
        assert_eq!(roulette(0.5, 1.0, 0.9), None);
    }
}
