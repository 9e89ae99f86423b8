//! Sensor noise: a table of Gaussian quantiles indexed by 16 random bits.

/// Number of quantiles in the table (indexed by 16 random bits).
pub(crate) const TABLE_LEN: usize = 1 << 16;

/// Gaussian noise, rounded to whole 0..255 units: entry `i` is the `(i + ½) / 65536` quantile of
/// a normal distribution with the given standard deviation. The table is exactly antisymmetric,
/// so the noise has zero mean.
pub(crate) fn gaussian_table(stddev: f64) -> Vec<i16> {
    let mut table = vec![0i16; TABLE_LEN];
    for i in 0..TABLE_LEN / 2 {
        let p = (i as f64 + 0.5) / TABLE_LEN as f64;
        let v = (stddev * inverse_normal_cdf(p))
            .round()
            .clamp(-510.0, 510.0) as i16;
        table[i] = v;
        table[TABLE_LEN - 1 - i] = -v;
    }
    table
}

/// Acklam's rational approximation of the standard normal quantile function (relative error
/// below 1.2e-9), for `p` in (0, 1).
pub(crate) fn inverse_normal_cdf(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const P_LOW: f64 = 0.02425;
    if !(p > 0.0 && p < 1.0) {
        return 0.0;
    }
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < P_LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p <= 1.0 - P_LOW {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_are_standard_normal() {
        assert!(inverse_normal_cdf(0.5).abs() < 1e-12);
        assert!((inverse_normal_cdf(0.975) - 1.959_963_985).abs() < 1e-7);
        assert!((inverse_normal_cdf(0.001) + 3.090_232_306).abs() < 1e-7);
    }

    #[test]
    fn table_has_zero_mean_and_the_asked_spread() {
        let t = gaussian_table(5.0);
        let n = t.len() as f64;
        let mean = t.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let var = t.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>() / n;
        assert_eq!(mean, 0.0);
        // Rounding adds 1/12 of a unit to the variance.
        assert!((var.sqrt() - 5.0).abs() < 0.1, "stddev {}", var.sqrt());
    }
}
