//! Small helpers on `[f64; N]` points and directions.

/// `a - b`.
pub(crate) fn sub<const N: usize>(a: &[f64; N], b: &[f64; N]) -> [f64; N] {
    let mut r = *a;
    r.iter_mut().zip(b).for_each(|(r, b)| *r -= b);
    r
}

/// `a + k * b`.
pub(crate) fn add_scaled<const N: usize>(a: &[f64; N], k: f64, b: &[f64; N]) -> [f64; N] {
    let mut r = *a;
    r.iter_mut().zip(b).for_each(|(r, b)| *r += k * b);
    r
}

/// `k * a`.
pub(crate) fn scale<const N: usize>(k: f64, a: &[f64; N]) -> [f64; N] {
    a.map(|x| k * x)
}

/// Dot product.
pub(crate) fn dot<const N: usize>(a: &[f64; N], b: &[f64; N]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// Euclidean norm.
pub(crate) fn norm<const N: usize>(a: &[f64; N]) -> f64 {
    dot(a, a).sqrt()
}

/// Coordinate `i`, or 0 when out of range.
pub(crate) fn get<const N: usize>(a: &[f64; N], i: usize) -> f64 {
    a.get(i).copied().unwrap_or(0.0)
}

/// Set coordinate `i` (ignored when out of range).
pub(crate) fn set<const N: usize>(a: &mut [f64; N], i: usize, v: f64) {
    if let Some(x) = a.get_mut(i) {
        *x = v;
    }
}
