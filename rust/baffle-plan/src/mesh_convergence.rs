//! Discretization uncertainty of a three-mesh study: Roache's grid convergence index with
//! the observed order, as Celik et al. (2008, "Procedure for Estimation and Reporting of
//! Uncertainty Due to Discretization in CFD Applications", J. Fluids Eng. 130: 078001)
//! give it for unequal refinement ratios. `scripts/validation/gci.py` is the same
//! procedure in Python (the validation tables); the two are tested on Celik's example.
//!
//! A level's representative size is h = (V / N)^(1/3) for N tetrahedra filling V mm³.
//! Level 1 is the finest. The observed order p solves (Celik eq. 3a-c)
//! p = |ln|e32/e21| + q(p)| / ln r21,  q(p) = ln((r21^p - s) / (r32^p - s)),  s = sign(e32/e21),
//! by fixed-point iteration; the extrapolated value is (r21^p f1 - f2) / (r21^p - 1) (eq. 4)
//! and GCI_fine = Fs e_a21 / (r21^p - 1) (eq. 5) with Fs = 1.25.

/// Safety factor of the GCI when the observed order is credible (three meshes).
pub const SAFETY_FACTOR: f64 = 1.25;
/// Roache's conservative choice when the observed order cannot be trusted: the scheme's
/// formal order (P1-P1 stabilized elements: 2) with safety factor 3.
pub const FORMAL_ORDER: f64 = 2.0;
pub const CONSERVATIVE_SAFETY_FACTOR: f64 = 3.0;
/// An observed order outside this range says the levels are not in the asymptotic range.
pub const CREDIBLE_ORDER: (f64, f64) = (0.5, 3.0);

/// One mesh of a study and the value it gave.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Level {
    pub edge_length_mm: f64,
    pub tetrahedra: usize,
    pub volume_mm3: f64,
    pub value: f64,
}

impl Level {
    /// Celik's representative cell size (mm).
    pub fn h_mm(&self) -> f64 {
        (self.volume_mm3 / self.tetrahedra as f64).cbrt()
    }
}

/// The study's result for one quantity.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Convergence {
    pub observed_order: f64,
    /// Richardson extrapolation to zero mesh size.
    pub extrapolated: f64,
    /// |f1 - f2| / |f1|: the finest two levels' relative difference.
    pub relative_change_fine: f64,
    /// The levels' differences change sign: no monotone convergence.
    pub oscillatory: bool,
    /// Observed order within [`CREDIBLE_ORDER`] and monotone.
    pub asymptotic: bool,
    /// The relative uncertainty of the finest value: GCI_fine when `asymptotic`, else the
    /// conservative index at the formal order.
    pub gci_fine: f64,
    /// `gci_fine` in the quantity's unit (|f1| x gci_fine).
    pub band: f64,
}

/// Observed order from three levels (h ascending: finest first).
fn observed_order(h: [f64; 3], f: [f64; 3]) -> Result<f64, String> {
    let (e21, e32) = (f[1] - f[0], f[2] - f[1]);
    if e21 == 0.0 || e32 == 0.0 {
        return Err(format!("two mesh levels give the same value ({:?}): the observed order is undefined", f));
    }
    let (r21, r32) = (h[1] / h[0], h[2] / h[1]);
    let s = (e32 / e21).signum();
    let ratio = (e32 / e21).abs().ln();
    let mut p = ratio.abs() / r21.ln();
    for _ in 0..200 {
        let q = ((r21.powf(p) - s) / (r32.powf(p) - s)).ln();
        let next = (ratio + q).abs() / r21.ln();
        if !next.is_finite() {
            return Err(format!("the observed order does not converge for the values {:?}", f));
        }
        if (next - p).abs() < 1e-10 {
            return Ok(next);
        }
        p = next;
    }
    Ok(p)
}

/// The GCI of three levels given in any order (sorted here finest first).
pub fn grid_convergence(levels: &[Level; 3]) -> Result<Convergence, String> {
    let mut sorted = *levels;
    sorted.sort_by(|a, b| a.h_mm().total_cmp(&b.h_mm()));
    let h = sorted.map(|l| l.h_mm());
    let f = sorted.map(|l| l.value);
    if !(h.iter().chain(&f).all(|v| v.is_finite()) && h[0] > 0.0) {
        return Err(format!("a mesh level has no finite size or value: h {h:?} mm, values {f:?}"));
    }
    if !(h[0] < h[1] && h[1] < h[2]) {
        return Err(format!("the three meshes must differ in size, got h = {h:?} mm"));
    }
    let p = observed_order(h, f)?;
    let r21p = (h[1] / h[0]).powf(p);
    let relative_change_fine = ((f[0] - f[1]) / f[0]).abs();
    let oscillatory = (f[2] - f[1]) * (f[1] - f[0]) < 0.0;
    let asymptotic = (CREDIBLE_ORDER.0..=CREDIBLE_ORDER.1).contains(&p) && !oscillatory;
    let gci_fine = if asymptotic {
        SAFETY_FACTOR * relative_change_fine / (r21p - 1.0)
    } else {
        CONSERVATIVE_SAFETY_FACTOR * relative_change_fine / ((h[1] / h[0]).powf(FORMAL_ORDER) - 1.0)
    };
    Ok(Convergence {
        observed_order: p,
        extrapolated: (r21p * f[0] - f[1]) / (r21p - 1.0),
        relative_change_fine,
        oscillatory,
        asymptotic,
        gci_fine,
        band: f[0].abs() * gci_fine,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Levels of size h (V = 1 mm³, so N = h^-3) and values f.
    fn levels(h: [f64; 3], f: [f64; 3]) -> [Level; 3] {
        [0, 1, 2].map(|k| Level { edge_length_mm: h[k], tetrahedra: 1, volume_mm3: h[k].powi(3), value: f[k] })
    }

    #[test]
    fn celik_example_one() {
        // Celik et al. 2008, Table 1, phi = dimensionless reattachment length: N 18000, 8000,
        // 4500 (2D: h = (1/N)^(1/2)), phi 6.063, 5.972, 5.863 -> p 1.53, extrapolated 6.1685,
        // GCI_fine 2.17 %.
        let h = [18000.0, 8000.0, 4500.0].map(|n: f64| (1.0 / n).sqrt());
        let c = grid_convergence(&levels(h, [6.063, 5.972, 5.863])).unwrap();
        assert!((c.observed_order - 1.53).abs() < 0.01, "{c:?}");
        assert!((c.extrapolated - 6.1685).abs() < 2e-3, "{c:?}");
        assert!((c.gci_fine - 0.0217).abs() < 5e-4 && c.asymptotic, "{c:?}");
    }

    #[test]
    fn a_second_order_quantity_extrapolates_to_its_limit_whatever_the_level_order() {
        let h = [0.6, 0.75, 0.95];
        let f = h.map(|h| 4.5 + 1.2 * h * h);
        let mut given = levels(h, f);
        given.reverse();
        let c = grid_convergence(&given).unwrap();
        assert!((c.observed_order - 2.0).abs() < 1e-6 && (c.extrapolated - 4.5).abs() < 1e-9, "{c:?}");
        // The fine value's true error is 1.2 * 0.36 = 0.432; the GCI (Fs 1.25) covers it.
        assert!(c.band > 0.432 && c.band < 0.6, "{c:?}");
    }

    #[test]
    fn oscillating_levels_get_the_conservative_band() {
        let c = grid_convergence(&levels([0.6, 0.75, 0.95], [1.58, 1.70, 1.14])).unwrap();
        assert!(c.oscillatory && !c.asymptotic, "{c:?}");
        let expected = CONSERVATIVE_SAFETY_FACTOR * (0.12 / 1.58) / ((0.75f64 / 0.6).powi(2) - 1.0);
        assert!((c.gci_fine - expected).abs() < 1e-12, "{c:?}");
    }

    #[test]
    fn equal_values_or_sizes_are_named_errors() {
        assert!(grid_convergence(&levels([0.6, 0.75, 0.95], [2.0, 2.0, 2.5])).unwrap_err().contains("same value"));
        assert!(grid_convergence(&levels([0.6, 0.6, 0.95], [2.0, 2.1, 2.5])).unwrap_err().contains("differ in size"));
        assert!(grid_convergence(&levels([0.6, 0.75, 0.95], [f64::NAN, 2.1, 2.5])).unwrap_err().contains("finite"));
    }
}
