//! First pair of spheres overlapping by more than a fraction of the smaller radius,
//! found with a hash grid: O(N) memory whatever the packing, so an absurd case (1e6
//! grains in a millimetre box) is refused instead of exhausting memory.

use crate::numerics::vec3::{V3, dot, sub};
use std::collections::HashMap;

/// The cell `k + d`, saturating: a position that is not finite or beyond i64 cells (a
/// case with `x = inf` or 1e300, refused by the case's validation with a message) maps
/// to the extreme cell instead of overflowing, so the search runs before validation
/// without a panic; distances are still computed exactly.
fn neighbour(k: [i64; 3], d: [i64; 3]) -> [i64; 3] {
    std::array::from_fn(|c| k[c].saturating_add(d[c]))
}

pub(crate) fn first_overlap(x: &[V3], r: &[f64], max_frac: f64) -> Option<(usize, usize, f64)> {
    let rmax = r.iter().copied().fold(0.0, f64::max);
    if x.len() < 2 || rmax <= 0.0 {
        return None;
    }
    let cell = 2.0 * rmax;
    let key = |p: &V3| -> [i64; 3] { std::array::from_fn(|c| (p[c] / cell).floor() as i64) };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in x.iter().enumerate() {
        let k = key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let n = neighbour(k, [dx, dy, dz]);
                    if let Some(others) = grid.get(&n) {
                        for &j in others {
                            let d = sub(x[i], x[j]);
                            let reach = r[i] + r[j];
                            let d2 = dot(d, d);
                            if d2 < reach * reach {
                                let overlap = reach - d2.sqrt();
                                if overlap > max_frac * r[i].min(r[j]) {
                                    return Some((j, i, overlap));
                                }
                            }
                        }
                    }
                }
            }
        }
        grid.entry(k).or_default().push(i);
    }
    None
}

/// First pair of spheres of different bodies (`body[i] < 0`: a free sphere) that touch
/// or overlap (gap <= 0), with its gap: LIGGGHTS' insertion of clumps refuses any such
/// contact. Same hash grid as [`first_overlap`], so O(N) whatever the count.
pub(crate) fn first_contact_across_bodies(
    x: &[V3],
    r: &[f64],
    body: &[i32],
) -> Option<(usize, usize, f64)> {
    let rmax = r.iter().copied().fold(0.0, f64::max);
    if x.len() < 2 || rmax <= 0.0 {
        return None;
    }
    let cell = 2.0 * rmax;
    let key = |p: &V3| -> [i64; 3] { std::array::from_fn(|c| (p[c] / cell).floor() as i64) };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in x.iter().enumerate() {
        let k = key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let n = neighbour(k, [dx, dy, dz]);
                    for &j in grid.get(&n).into_iter().flatten() {
                        if body[i] >= 0 && body[i] == body[j] {
                            continue;
                        }
                        let d = sub(x[i], x[j]);
                        let gap = dot(d, d).sqrt() - (r[i] + r[j]);
                        if gap <= 0.0 {
                            return Some((j, i, gap));
                        }
                    }
                }
            }
        }
        grid.entry(k).or_default().push(i);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_coincident_and_ignores_touching() {
        let x = [[0.0; 3], [2.0, 0.0, 0.0], [4.0, 0.0, 0.0], [4.0, 0.0, 0.0]];
        let r = [1.0; 4];
        assert_eq!(first_overlap(&x, &r, 0.05), Some((2, 3, 2.0)));
        assert_eq!(first_overlap(&x[..3], &r[..3], 0.05), None);
        // 4 % of the radius passes a 5 % limit, 6 % does not.
        let y = [[0.0; 3], [1.96, 0.0, 0.0]];
        assert_eq!(first_overlap(&y, &r[..2], 0.05), None);
        let z = [[0.0; 3], [1.94, 0.0, 0.0]];
        assert!(first_overlap(&z, &r[..2], 0.05).is_some());
    }

    #[test]
    fn contacts_between_bodies_skip_members_of_one_body() {
        // Two dimers: members of one body overlap by design; the bodies do not touch.
        let x = [[0.0; 3], [1.5, 0.0, 0.0], [0.0, 2.5, 0.0], [1.5, 2.5, 0.0]];
        let r = [1.0; 4];
        assert_eq!(first_contact_across_bodies(&x, &r, &[0, 0, 1, 1]), None);
        // Closer: sphere 0 (body 0) and sphere 2 (body 1) touch with gap -0.1.
        let y = [[0.0; 3], [1.5, 0.0, 0.0], [0.0, 1.9, 0.0], [1.5, 5.0, 0.0]];
        let (i, j, gap) = first_contact_across_bodies(&y, &r, &[0, 0, 1, 1]).unwrap();
        assert_eq!((i, j), (0, 2));
        assert!((gap + 0.1).abs() < 1e-12);
        // Exactly touching counts (gap 0), a free sphere (-1) touches any body.
        let z = [[0.0; 3], [2.0, 0.0, 0.0]];
        assert_eq!(
            first_contact_across_bodies(&z, &r[..2], &[-1, 0]),
            Some((0, 1, 0.0))
        );
    }
}
