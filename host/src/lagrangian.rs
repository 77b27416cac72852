//! The one rate of a Lagrangian allocation: every part (a grid's widths, a base triangle's
//! level) takes the choice where a bit or byte saved would cost more squared error than one
//! rate all parts share, so the whole takes the least error for its size. The rate that just
//! meets a bound on the whole is found by bisection of its logarithm.
//!
//! Guarantees: the rate returned lies on the side of the boundary that fits, wherever fitting
//! changes once over `[1e-30, 1e30]`; where nothing in that range fits, the end nearest to it.

/// The last rate that `fits`, where the rates below it fit (`low_fits`, as for an error bound:
/// a lower rate spends more to err less) or the rates above it do (as for a size budget).
pub fn bisect_rate(low_fits: bool, fits: impl Fn(f64) -> bool) -> f64 {
    let (mut low, mut high) = (1e-30f64, 1e30f64);
    for _ in 0..100 {
        let mid = (low * high).sqrt();
        if fits(mid) == low_fits {
            low = mid;
        } else {
            high = mid;
        }
    }
    if low_fits {
        low
    } else {
        high
    }
}
