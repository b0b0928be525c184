//! An upright cylinder (a robot's body) swept against a box, in closed form.
//!
//! Every tick a robot flies, its body is swept through the scene ([`crate::scene`]); near a
//! wall, floor or ceiling that is a shape cast of a cylinder against a box. parry answers it
//! with GJK (iterations of support points and simplex projections), which a profile of the
//! Python environments' random flight showed taking a quarter of all the time. For a
//! cylinder standing along the box's z axis the distance separates: the squared distance is
//! the squared distance of the disc to the rectangle (in x, y) plus that of the two
//! intervals (in z). So the body is within `d` of the box exactly when its centre is in the
//! box grown by the cylinder and then by a ball of radius `d`; a face of that shape is a
//! line crossing a rounded rectangle or a slab, solved here directly. Only where the cast
//! meets the rounded rim (a hit on an edge, not a face) is the time found by bisection.
//!
//! Conventions are parry's for a support-map cast with a target distance and
//! `stop_at_penetration = false`: the time is where the distance first falls to the target;
//! a cast that starts within the target (or hits before 10⁻⁴ of its motion) hits at once
//! unless it moves away from the box along the contact normal, then it hits nothing.

/// A plain f64 vector in the box's frame.
type V3 = [f64; 3];

/// The outcome of a cast: the fraction of the motion, and the box's outward normal there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hit {
    /// Fraction of the motion travelled before the body comes within the target distance.
    pub(crate) toi: f64,
    /// Unit normal of the box where it is nearest the body (pointing out of the box).
    pub(crate) normal: V3,
    /// The nearest point of the box.
    pub(crate) point: V3,
    /// Whether the body started within the target distance (or overlapping the box).
    pub(crate) within: bool,
}

/// A box centred at the origin (`half` extents) and an upright cylinder.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Pair {
    /// The box's half extents.
    pub(crate) half: V3,
    /// The cylinder's radius.
    pub(crate) radius: f64,
    /// The cylinder's half height (along z).
    pub(crate) half_height: f64,
}

/// Below this fraction of the motion, parry decides a hit by the contact normal at the start.
const EARLY: f64 = 1e-4;

/// The length of `e`, as `hypot` (+0 for zeros of either sign) without its call for a
/// centre over the box (where the body of a robot on a floor or under a ceiling is).
fn planar(e: [f64; 2]) -> f64 {
    if e[0] == 0.0 && e[1] == 0.0 {
        0.0
    } else {
        e[0].hypot(e[1])
    }
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn at(c: V3, v: V3, t: f64) -> V3 {
    [c[0] + t * v[0], c[1] + t * v[1], c[2] + t * v[2]]
}

/// Times where `p + t v` lies in `lo..=hi` (every `t` if `v` is 0 and `p` is inside).
fn slab(p: f64, v: f64, lo: f64, hi: f64) -> Option<(f64, f64)> {
    if v == 0.0 {
        return (lo <= p && p <= hi).then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    let (a, b) = ((lo - p) / v, (hi - p) / v);
    Some((a.min(b), a.max(b)))
}

fn meet(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    let ((a0, a1), (b0, b1)) = (a?, b?);
    let span = (a0.max(b0), a1.min(b1));
    (span.0 <= span.1).then_some(span)
}

fn join(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
        (one, None) | (None, one) => one,
    }
}

/// Times where the 2D point `p + t v` is within `r` of `centre`.
fn disc(p: [f64; 2], v: [f64; 2], centre: [f64; 2], r: f64) -> Option<(f64, f64)> {
    let d = [p[0] - centre[0], p[1] - centre[1]];
    let a = v[0] * v[0] + v[1] * v[1];
    let c = d[0] * d[0] + d[1] * d[1] - r * r;
    if a == 0.0 {
        return (c <= 0.0).then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    let b = v[0] * d[0] + v[1] * d[1];
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    Some(((-b - s) / a, (-b + s) / a))
}

/// Times where the 2D point `p + t v` is within `r` of the rectangle `±h`: the union of two
/// crossed boxes and four corner discs (convex, so the union of their spans is one span).
fn rounded_rect(p: [f64; 2], v: [f64; 2], h: [f64; 2], r: f64) -> Option<(f64, f64)> {
    let wide = meet(
        slab(p[0], v[0], -h[0] - r, h[0] + r),
        slab(p[1], v[1], -h[1], h[1]),
    );
    let tall = meet(
        slab(p[0], v[0], -h[0], h[0]),
        slab(p[1], v[1], -h[1] - r, h[1] + r),
    );
    let mut span = join(wide, tall);
    for (sx, sy) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        span = join(span, disc(p, v, [sx * h[0], sy * h[1]], r));
    }
    span
}

impl Pair {
    /// The shortest vector from the box to the cylinder centred at `c`; zero if they meet.
    fn separation(&self, c: V3) -> V3 {
        let h = self.half;
        let e = [
            c[0] - c[0].clamp(-h[0], h[0]),
            c[1] - c[1].clamp(-h[1], h[1]),
        ];
        let len = planar(e);
        let out = (len - self.radius).max(0.0);
        let (x, y) = if out > 0.0 {
            (e[0] / len * out, e[1] / len * out)
        } else {
            (0.0, 0.0)
        };
        let z = (c[2].abs() - (h[2] + self.half_height)).max(0.0);
        [x, y, z.copysign(c[2])]
    }

    /// The way out of the box for a cylinder at `c` overlapping it: the direction of least
    /// depth (a unit vector).
    fn way_out(&self, c: V3) -> V3 {
        let h = self.half;
        let up = if c[2] < 0.0 { -1.0 } else { 1.0 };
        let mut best = (h[2] + self.half_height - c[2].abs(), [0.0, 0.0, up]);
        let e = [
            c[0] - c[0].clamp(-h[0], h[0]),
            c[1] - c[1].clamp(-h[1], h[1]),
        ];
        let len = planar(e);
        let sides = if len > 0.0 {
            vec![(self.radius - len, [e[0] / len, e[1] / len, 0.0])]
        } else {
            vec![
                (
                    h[0] - c[0].abs() + self.radius,
                    [1f64.copysign(c[0]), 0.0, 0.0],
                ),
                (
                    h[1] - c[1].abs() + self.radius,
                    [0.0, 1f64.copysign(c[1]), 0.0],
                ),
            ]
        };
        for side in sides {
            if side.0 < best.0 {
                best = side;
            }
        }
        best.1
    }

    /// The box's outward normal nearest a cylinder at `c`, and the box's nearest point.
    fn contact(&self, c: V3) -> (V3, V3) {
        let w = self.separation(c);
        (self.normal(c, w, dot(w, w).sqrt()), self.nearest(c))
    }

    /// The box's outward normal nearest a cylinder at `c` whose [`Pair::separation`] is `w`,
    /// of length `len`.
    fn normal(&self, c: V3, w: V3, len: f64) -> V3 {
        if len > 0.0 {
            [w[0] / len, w[1] / len, w[2] / len]
        } else {
            self.way_out(c)
        }
    }

    /// The box's point nearest `c`.
    fn nearest(&self, c: V3) -> V3 {
        let h = self.half;
        std::array::from_fn(|i| c[i].clamp(-h[i], h[i]))
    }

    fn distance(&self, c: V3) -> f64 {
        let w = self.separation(c);
        dot(w, w).sqrt()
    }

    /// The times in `0..=max` at which the centre `c + t v` is in the box grown by the
    /// cylinder and then by a cube of side `2 target` (it holds the grown-by-a-ball shape,
    /// and on its faces the two agree), as `(entry, exit)`; `None` when there are none.
    /// With `over_face`, a motion that keeps the centre over the box's rectangle (its
    /// start and end inside it, a micrometre from its edges) skips the rounded rectangle:
    /// its span then holds all of `0..=max` (its crossed boxes reach `radius + target`
    /// beyond the rectangle on one axis, and the micrometre covers the rounding on the
    /// other), so the entry and exit are the vertical slab's, bit for bit — the cast of a
    /// body approaching a floor or a ceiling from above or below it.
    fn window(&self, c: V3, v: V3, target: f64, max: f64, over_face: bool) -> Option<(f64, f64)> {
        let h = self.half;
        let flat = slab(
            c[2],
            v[2],
            -(h[2] + self.half_height + target),
            h[2] + self.half_height + target,
        );
        let grown = if over_face && self.over_face(c, v, max) {
            flat?
        } else {
            meet(
                rounded_rect(
                    [c[0], c[1]],
                    [v[0], v[1]],
                    [h[0], h[1]],
                    self.radius + target,
                ),
                flat,
            )?
        };
        let (entry, exit) = (grown.0.max(0.0), grown.1.min(max));
        if entry > exit {
            return None;
        }
        Some((entry, exit))
    }

    /// Whether the centre starts and ends (at `max`) over the box's rectangle, a micrometre
    /// (more than any rounding of these coordinates, at most the world's 100 km) inside its
    /// edges: [`Pair::window`]'s shortcut.
    fn over_face(&self, c: V3, v: V3, max: f64) -> bool {
        const IN: f64 = 1e-6;
        (0..2).all(|i| {
            let end = c[i] + max * v[i];
            c[i].abs() <= self.half[i] - IN && end.abs() <= self.half[i] - IN
        })
    }

    /// The cylinder, centred at `c`, moved by `v` times `0..=max`: where it first comes
    /// within `target` of the box, parry's way (see the module's text).
    pub(crate) fn cast(&self, c: V3, v: V3, target: f64, max: f64) -> Option<Hit> {
        let hit = |toi: f64, within: bool| {
            let (normal, point) = self.contact(at(c, v, toi));
            Hit {
                toi,
                normal,
                point,
                within,
            }
        };
        // The start's separation, read once for its distance and its normal.
        let w = self.separation(c);
        let start = dot(w, w).sqrt();
        let decide_at_start = |toi: f64, within: bool| {
            let normal = self.normal(c, w, start);
            (dot(normal, v) < 0.0).then(|| Hit {
                toi,
                normal,
                point: self.nearest(at(c, v, toi)),
                within,
            })
        };
        if start <= target {
            return decide_at_start(0.0, true);
        }
        let (entry, exit) = self.window(c, v, target, max, true)?;
        let f = |t: f64| self.distance(at(c, v, t));
        let mut toi = entry;
        // On a face the entry is the answer (to rounding); past it, on the rounded rim, the
        // distance (convex in t) is minimised and the first time at the target bisected.
        if f(toi) > target * (1.0 + 1e-9) {
            let (mut a, mut b) = (entry, exit);
            for _ in 0..100 {
                let (m1, m2) = (a + (b - a) * 0.382, a + (b - a) * 0.618);
                if f(m1) <= f(m2) {
                    b = m2;
                } else {
                    a = m1;
                }
            }
            let low = (a + b) * 0.5;
            if f(low) > target {
                return None;
            }
            let (mut out, mut inside) = (entry, low);
            for _ in 0..100 {
                let mid = (out + inside) * 0.5;
                if f(mid) > target {
                    out = mid;
                } else {
                    inside = mid;
                }
            }
            toi = out;
        }
        if toi < EARLY {
            return decide_at_start(toi, false);
        }
        Some(hit(toi, false))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BOX: Pair = Pair {
        half: [1.0, 2.0, 0.5],
        radius: 0.3,
        half_height: 0.1,
    };

    #[test]
    fn a_body_falling_onto_a_box_stops_at_the_target_distance_above_its_top() {
        let hit = BOX
            .cast([0.2, 0.3, -2.0], [0.0, 0.0, 3.0], 0.01, 1.0)
            .unwrap();
        // From z = -2 the body's bottom (-1.9) reaches the top (-0.5) less 0.01 after 1.39 m.
        assert!((hit.toi * 3.0 - 1.39).abs() < 1e-12, "{hit:?}");
        assert_eq!(hit.normal, [0.0, 0.0, -1.0]);
        assert!(!hit.within);
    }

    #[test]
    fn a_body_flying_past_a_box_or_away_from_it_hits_nothing() {
        assert_eq!(BOX.cast([0.0, 3.0, -2.0], [0.0, 0.0, 3.0], 0.01, 1.0), None);
        assert_eq!(
            BOX.cast([0.0, 0.0, -0.6], [0.0, 0.0, -1.0], 0.01, 1.0),
            None
        );
        // Touching the top and sliding along it.
        assert_eq!(
            BOX.cast([0.0, 0.0, -0.605], [1.0, 0.0, 0.0], 0.01, 1.0),
            None
        );
    }

    #[test]
    fn a_body_within_the_target_and_pressing_in_hits_at_once() {
        let hit = BOX
            .cast([0.0, 0.0, -0.605], [0.0, 0.0, 1.0], 0.01, 1.0)
            .unwrap();
        assert_eq!(
            (hit.toi, hit.normal, hit.within),
            (0.0, [0.0, 0.0, -1.0], true)
        );
    }

    #[test]
    fn a_body_meeting_a_vertical_edge_stops_on_the_rounded_corner() {
        // Towards the corner (1, 2) along the diagonal: the centre stops 0.3 + 0.01 from it.
        let c = [2.0, 3.0, 0.0];
        let v = [-1.0, -1.0, 0.0];
        let hit = BOX.cast(c, v, 0.01, 1.0).unwrap();
        let p = at(c, v, hit.toi);
        let gap = (p[0] - 1.0).hypot(p[1] - 2.0);
        assert!((gap - 0.31).abs() < 1e-9, "gap {gap}");
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!((hit.normal[0] - s).abs() < 1e-9 && (hit.normal[1] - s).abs() < 1e-9);
    }

    #[test]
    fn a_body_meeting_the_top_rim_stops_on_the_rounded_edge() {
        // Diagonally down onto the top edge at x = 1, entering the grown box at its corner
        // (x = 1.31, z = -0.61), where the body is still 0.01 × √2 away.
        let c = [1.7, 0.0, -1.0];
        let v = [-1.0, 0.0, 1.0];
        let hit = BOX.cast(c, v, 0.01, 1.0).unwrap();
        assert!(hit.toi > 0.39 + 1e-3, "{hit:?}");
        let d = BOX.distance(at(c, v, hit.toi));
        assert!((d - 0.01).abs() < 1e-9, "distance {d}");
        assert!(hit.normal[0] > 0.0 && hit.normal[2] < 0.0, "{hit:?}");
    }

    /// Uniform numbers in [0, 1) from a xorshift stream seeded with `seed`.
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn a_cast_over_the_face_skips_the_rounded_rectangle_bit_for_bit() {
        let mut unit = uniform(0x5851_F42D_4C95_7F2D);
        let (mut short, mut hits) = (0, 0);
        for k in 0..200_000 {
            // Some floors kilometres wide, their centres' offsets as large.
            let wide = if k % 4 == 0 { 5e4 } else { 50.0 };
            let pair = Pair {
                half: [
                    0.05 + wide * unit(),
                    0.05 + wide * unit(),
                    0.05 + 2.0 * unit(),
                ],
                radius: 0.1 + 0.5 * unit(),
                half_height: 0.05 + 0.2 * unit(),
            };
            // Centres over the rectangle, up to its edges and past them, above or below the
            // box.
            let past = if k % 3 == 0 { 1.0 } else { 0.01 };
            let edge = |u: f64, h: f64| (2.0 * u - 1.0) * (h + past);
            let side = if unit() < 0.5 { -1.0 } else { 1.0 };
            let gap = pair.half[2] + pair.half_height + 0.3 * unit();
            let c = [
                edge(unit(), pair.half[0]),
                edge(unit(), pair.half[1]),
                side * gap,
            ];
            let v = [
                (unit() - 0.5) * 0.2,
                (unit() - 0.5) * 0.2,
                -side * 0.5 * unit(),
            ];
            let v = if k % 7 == 0 { [0.0, 0.0, v[2]] } else { v };
            let (a, b) = (
                pair.window(c, v, 0.01, 1.0, true),
                pair.window(c, v, 0.01, 1.0, false),
            );
            assert_eq!(
                a.map(|(x, y)| (x.to_bits(), y.to_bits())),
                b.map(|(x, y)| (x.to_bits(), y.to_bits())),
                "{pair:?} {c:?} {v:?}"
            );
            short += usize::from(pair.over_face(c, v, 1.0));
            hits += usize::from(a.is_some());
        }
        assert!(
            short > 50_000 && hits > 20_000,
            "{short} shortcuts, {hits} hits"
        );
    }

    /// parry's GJK cast (the default dispatcher) on the same pair, as (fraction, normal).
    fn parry(pair: Pair, c: V3, v: V3, target: f64) -> Option<(f64, V3)> {
        use rapier3d::math::{Pose, Rotation, Vector};
        use rapier3d::parry::query::{DefaultQueryDispatcher, QueryDispatcher, ShapeCastOptions};
        use rapier3d::parry::shape::{Cuboid, Cylinder};
        let f = |a: V3| Vector::new(a[0] as f32, a[1] as f32, a[2] as f32);
        let cuboid = Cuboid::new(f(pair.half));
        let cylinder = Cylinder::new(pair.half_height as f32, pair.radius as f32);
        let pos12 = Pose::from_parts(f(c), Rotation::from_rotation_x(std::f32::consts::FRAC_PI_2));
        let options = ShapeCastOptions {
            max_time_of_impact: 1.0,
            target_distance: target as f32,
            stop_at_penetration: false,
            compute_impact_geometry_on_penetration: true,
        };
        let hit = DefaultQueryDispatcher
            .cast_shapes(&pos12, f(v), &cuboid, &cylinder, options)
            .ok()??;
        let n = hit.normal1;
        Some((
            f64::from(hit.time_of_impact),
            [f64::from(n.x), f64::from(n.y), f64::from(n.z)],
        ))
    }

    #[test]
    fn the_closed_form_agrees_with_parrys_gjk_on_random_casts() {
        let mut unit = uniform(0x9E37_79B9_7F4A_7C15);
        let (mut hits, mut compared) = (0, 0);
        for _ in 0..4000 {
            let pair = Pair {
                half: [0.1 + 3.0 * unit(), 0.1 + 3.0 * unit(), 0.1 + 3.0 * unit()],
                radius: 0.1 + 0.5 * unit(),
                half_height: 0.05 + 0.2 * unit(),
            };
            let c: V3 = std::array::from_fn(|i| (unit() - 0.5) * 4.0 * (pair.half[i] + 1.0));
            let v: V3 = std::array::from_fn(|_| (unit() - 0.5) * 6.0);
            let target = 0.01;
            let ours = pair.cast(c, v, target, 1.0);
            let theirs = parry(pair, c, v, target);
            let speed = dot(v, v).sqrt();
            match (ours, theirs) {
                (Some(a), Some((toi, n))) => {
                    hits += 1;
                    // Ours stops exactly at the target distance; parry's GJK within its
                    // tolerance of it (tenths of a millimetre here, either way).
                    if !a.within {
                        let d = pair.distance(at(c, v, a.toi));
                        assert!(
                            (d - target).abs() < 1e-9,
                            "{pair:?} {c:?} {v:?}: {a:?} at {d}"
                        );
                    }
                    let d = pair.distance(at(c, v, toi));
                    assert!(
                        a.within || (toi - a.toi).abs() * speed < 2e-3 && (d - target).abs() < 1e-3,
                        "{pair:?} {c:?} {v:?}: {a:?} vs {toi} (distance {d})"
                    );
                    if a.toi > EARLY {
                        compared += 1;
                        assert!(
                            dot(a.normal, n) > 0.99,
                            "{pair:?} {c:?} {v:?}: {a:?} vs {n:?}"
                        );
                    }
                }
                (None, None) => {}
                // Only a graze decides differently: the body passes within a millimetre of
                // the target distance.
                (one, other) => {
                    let closest = (0..=1000)
                        .map(|i| pair.distance(at(c, v, f64::from(i) / 1000.0)))
                        .fold(f64::INFINITY, f64::min);
                    assert!(
                        (closest - target).abs() < 2e-3 || one.is_some_and(|h| h.within),
                        "{pair:?} {c:?} {v:?}: ours {one:?}, parry {other:?}, closest {closest}"
                    );
                }
            }
        }
        assert!(
            hits > 250 && compared > 200,
            "only {hits} hits, {compared} compared"
        );
    }
}
