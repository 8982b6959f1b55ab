//! Plane vectors as `[T; 2]`, counter-clockwise positive: the few operations
//! the impact model, the simulated plant and the tests share, written once.

use crate::real::Real;

/// `a + b`.
#[inline]
pub fn add<T: Real>(a: [T; 2], b: [T; 2]) -> [T; 2] {
    [a[0] + b[0], a[1] + b[1]]
}

/// `a - b`.
#[inline]
pub fn sub<T: Real>(a: [T; 2], b: [T; 2]) -> [T; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// `a . b`.
#[inline]
pub fn dot<T: Real>(a: [T; 2], b: [T; 2]) -> T {
    a[0] * b[0] + a[1] * b[1]
}

/// `a x b`, the z component of the cross product.
#[inline]
pub fn cross<T: Real>(a: [T; 2], b: [T; 2]) -> T {
    a[0] * b[1] - a[1] * b[0]
}

/// `|a|`, the Euclidean length.
#[inline]
pub fn norm<T: Real>(a: [T; 2]) -> T {
    dot(a, a).sqrt()
}

/// `z x r = (-r_y, r_x)`: `r` turned a quarter turn counter-clockwise.
#[inline]
pub fn perp<T: Real>(r: [T; 2]) -> [T; 2] {
    [-r[1], r[0]]
}

/// `omega x r = omega (-r_y, r_x)`: the velocity of the point `r` of a body
/// turning at `omega`, rad/s, about the origin.
#[inline]
pub fn spin<T: Real>(omega: T, r: [T; 2]) -> [T; 2] {
    [-omega * r[1], omega * r[0]]
}

/// `R(angle) v`, with `angle_cs = (sin angle, cos angle)`: `v` turned by the
/// angle, from a body's frame into the world's.
#[inline]
pub fn rotate<T: Real>(angle_cs: (T, T), v: [T; 2]) -> [T; 2] {
    let (s, c) = angle_cs;
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

/// `R(-angle) v = R(angle)^T v`, with `angle_cs = (sin angle, cos angle)`: a
/// world vector in the frame of a body turned by the angle.
#[inline]
pub fn unrotate<T: Real>(angle_cs: (T, T), v: [T; 2]) -> [T; 2] {
    let (s, c) = angle_cs;
    [c * v[0] + s * v[1], -s * v[0] + c * v[1]]
}
