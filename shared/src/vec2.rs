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

/// `R(angle) v`, with `sin_cos = (sin angle, cos angle)`: `v` turned by the
/// angle, from a body's frame into the world's.
#[inline]
pub fn rotate<T: Real>(sin_cos: (T, T), v: [T; 2]) -> [T; 2] {
    let (s, c) = sin_cos;
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

/// `R(-angle) v = R(angle)^T v`, with `sin_cos = (sin angle, cos angle)`: a
/// world vector in the frame of a body turned by the angle.
#[inline]
pub fn unrotate<T: Real>(sin_cos: (T, T), v: [T; 2]) -> [T; 2] {
    let (s, c) = sin_cos;
    [c * v[0] + s * v[1], -s * v[0] + c * v[1]]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against what the operations mean, with numbers exact in binary: the
    /// quarter and half turns, the cross product's sign (counter-clockwise
    /// positive), a 3-4-5 length, and a turn there and back.
    #[test]
    fn the_operations_mean_what_they_say() {
        let (x, y) = ([1.0f64, 0.0], [0.0f64, 1.0]);
        assert_eq!(add([1.0, 2.0], [3.0, 5.0]), [4.0, 7.0]);
        assert_eq!(sub([1.0, 2.0], [3.0, 5.0]), [-2.0, -3.0]);
        assert_eq!(dot([1.0, 2.0], [3.0, 5.0]), 13.0);
        assert_eq!(cross(x, y), 1.0, "x to y turns counter-clockwise");
        assert_eq!(cross(y, x), -1.0);
        assert_eq!(norm([3.0, 4.0]), 5.0);
        assert_eq!(perp(x), y, "a quarter turn counter-clockwise");
        // A body turning at +2 rad/s: its point on +x moves along +y.
        assert_eq!(spin(2.0, x), [0.0, 2.0]);
        assert_eq!(spin(2.0, y), [-2.0, 0.0]);
        // R(90 deg) and R(180 deg) by their sines and cosines.
        assert_eq!(rotate((1.0, 0.0), x), y);
        assert_eq!(rotate((0.0, -1.0), [2.0, 3.0]), [-2.0, -3.0]);
        assert_eq!(unrotate((1.0, 0.0), y), x);
        // R(-a) R(a) v = v, to rounding.
        let a = 0.7f64;
        let v = [0.3, -1.2];
        let back = unrotate(a.sin_cos(), rotate(a.sin_cos(), v));
        assert!((back[0] - v[0]).abs() < 1e-15 && (back[1] - v[1]).abs() < 1e-15);
        // The same in f32, as the firmware's impact model computes.
        assert_eq!(cross([1.0f32, 0.0], [0.0, 1.0]), 1.0);
    }
}
