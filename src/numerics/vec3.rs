//! Tiny fixed-size vector helpers for the hot loops. Plain `[f64; 3]` keeps the
//! structure-of-arrays layout trivially `Copy` and lets the operation order mirror
//! LIGGGHTS' C code line by line, which is what makes round-off-level agreement possible.

pub(crate) type V3 = [f64; 3];

#[inline(always)]
pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline(always)]
pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
pub fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline(always)]
pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
pub fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
#[inline(always)]
pub(crate) fn add_assign(a: &mut V3, b: V3) {
    a[0] += b[0];
    a[1] += b[1];
    a[2] += b[2];
}
#[inline(always)]
pub(crate) fn sub_assign(a: &mut V3, b: V3) {
    a[0] -= b[0];
    a[1] -= b[1];
    a[2] -= b[2];
}
