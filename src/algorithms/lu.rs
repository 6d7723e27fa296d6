//! In-place LU factorization with partial pivoting of a small dense matrix,
//! for the (unsymmetric) Newton matrix of the Newmark iteration with friction.

/// Factors the leading `n`×`n` block of the row-major buffer `a` into P·L·U
/// in place, recording row exchanges in `pivots`. Returns false if a pivot
/// is zero or not finite.
pub fn factor(a: &mut [f64], n: usize, pivots: &mut [usize]) -> bool {
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| a[i * n + k].abs().total_cmp(&a[j * n + k].abs())).unwrap_or(k);
        pivots[k] = p;
        if p != k {
            for c in 0..n {
                a.swap(k * n + c, p * n + c);
            }
        }
        let d = a[k * n + k];
        if d == 0.0 || !d.is_finite() {
            return false;
        }
        for i in k + 1..n {
            let f = a[i * n + k] / d;
            a[i * n + k] = f;
            for c in k + 1..n {
                a[i * n + c] -= f * a[k * n + c];
            }
        }
    }
    true
}

/// Solves A·x = b in place (`b` becomes x) with the factors from [`factor`].
#[inline(always)]
pub fn solve(lu: &[f64], n: usize, pivots: &[usize], b: &mut [f64]) {
    // Slices of the used sizes let the compiler drop the per-index bounds checks.
    let (lu, b) = (&lu[..n * n], &mut b[..n]);
    if n == 1 {
        // The common case of one slipping joint.
        b[0] /= lu[0];
        return;
    }
    for (k, &p) in pivots[..n].iter().enumerate() {
        b.swap(k, p);
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= lu[i * n + k] * b[k];
        }
        b[i] = s;
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= lu[i * n + k] * b[k];
        }
        b[i] = s / lu[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn solves_an_unsymmetric_system_that_needs_pivoting() {
        let a0 = [0.0, 2.0, 1.0, 3.0, -1.0, 0.5, 1.0, 4.0, -2.0];
        let x = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a0[i * 3 + j] * x[j]).sum()).collect();
        let mut a = a0;
        let mut p = [0; 3];
        assert!(super::factor(&mut a, 3, &mut p));
        super::solve(&a, 3, &p, &mut b);
        for i in 0..3 {
            assert!((b[i] - x[i]).abs() < 1e-14, "{b:?}");
        }
        let mut singular = [1.0, 2.0, 2.0, 4.0];
        assert!(!super::factor(&mut singular, 2, &mut p));
    }
}
