//! The camera's renderer: a ray per pixel through the scene, on the CPU, with no GPU and no
//! randomness (the same pixels on every run and at any thread count).
//!
//! One tree query gathers the solids a camera may see ([`Scene::view_solids`]); each solid
//! is projected to the rectangle of pixels its box covers, and only those pixels' rays are
//! tried on it, nearest solids first (a pixel whose ray already hit something nearer than
//! the solid's box skips it). Boxes and upright cylinders (walls, floors, robots, pillars)
//! are intersected in closed form; other shapes (meshes) with parry's ray casts. Pixel
//! rays are not normalised: ray `(i, j)` is `forward + u_i·right + v_j·down`, so the
//! parameter of a hit is its depth along the optical axis.
//!
//! Shading: the solid's colour ([`Look`]) times `AMBIENT + DIFFUSE · max(0, n·(−light))`
//! (Lambert, one directional light from above); the sky is [`SKY`].

use rapier3d::math::Vector;
use rapier3d::prelude::{ColliderHandle, Ray};

use crate::scene::{Look, Scene, V3, ViewShape, ViewSolid, upright_cylinder_toi};

/// Robots' segmentation ids are this plus their spawn number (modulo this); map solids
/// have 1, 2, ... in file order (boxes, cylinders, meshes); the sky 0.
pub const ROBOT_SEGMENT: u32 = 1 << 16;

/// The colour of pixels whose ray hits nothing within range.
pub const SKY: [u8; 3] = [150, 195, 235];
/// Light on faces turned away from the sun.
const AMBIENT: f32 = 0.4;
/// Light added on a face the sun hits head-on.
const DIFFUSE: f32 = 0.6;
/// Where the sunlight goes (z down: from above, a little from the south-west).
const LIGHT: [f32; 3] = [0.3, 0.2, 0.93];

/// What a camera saw: colour, depth and segmentation, row by row from the top-left pixel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Image {
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Colour, 3 bytes a pixel: R, G, B.
    pub rgb: Vec<u8>,
    /// Depth along the optical axis, m; `f32::INFINITY` where nothing is within range.
    pub depth: Vec<f32>,
    /// The segmentation id of the solid each pixel shows (0: nothing; see [`Look`]).
    pub segment: Vec<u32>,
}

impl Image {
    /// A black image of `width` × `height` pixels.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            rgb: vec![0; 3 * n],
            depth: vec![0.0; n],
            segment: vec![0; n],
        }
    }
}

/// Where a camera is and how it looks.
#[derive(Debug, Clone, Copy)]
pub(crate) struct View {
    /// The optical centre, world frame.
    pub(crate) origin: V3,
    /// Unit vectors: the optical axis, the image's right and its down, world frame.
    pub(crate) forward: V3,
    pub(crate) right: V3,
    pub(crate) down: V3,
    /// Horizontal field of view, rad (0 < fov < π).
    pub(crate) fov: f64,
    /// Pixels.
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// The farthest depth seen, m.
    pub(crate) range: f64,
}

fn v(a: V3) -> Vector {
    Vector::new(a[0] as f32, a[1] as f32, a[2] as f32)
}

/// A gathered solid with what the per-pixel loop needs.
struct Target<'s> {
    solid: ViewSolid<'s>,
    /// Pixel rectangle `[x0, x1) × [y0, y1)` its box may cover.
    rect: [usize; 4],
    /// No ray parameter (depth) below this can reach its box.
    near: f32,
    /// Cuboids: the origin, forward, right and down in the box's frame.
    local: [Vector; 4],
}

/// Renders `view` of `scene` (without the solid `exclude`, the camera's own robot) into
/// `image` (resized to the view).
pub(crate) fn render(
    scene: &Scene,
    view: &View,
    exclude: Option<ColliderHandle>,
    image: &mut Image,
) {
    let (w, h) = (view.width as usize, view.height as usize);
    let n = w * h;
    image.width = view.width;
    image.height = view.height;
    image.rgb.resize(3 * n, 0);
    image.depth.clear();
    image.depth.resize(n, view.range as f32);
    image.segment.clear();
    image.segment.resize(n, 0);
    let tan = (view.fov / 2.0).tan() as f32;
    let tan_v = tan * h as f32 / w as f32;
    let us: Vec<f32> = (0..w)
        .map(|i| ((2 * i + 1) as f32 / w as f32 - 1.0) * tan)
        .collect();
    let vs: Vec<f32> = (0..h)
        .map(|j| ((2 * j + 1) as f32 / h as f32 - 1.0) * tan_v)
        .collect();
    let (o, f, r, d) = (v(view.origin), v(view.forward), v(view.right), v(view.down));
    // The longest pixel ray (a corner's): a hit at distance s has depth ≥ s / longest.
    let longest = (1.0 + tan * tan + tan_v * tan_v).sqrt();
    // The box reached by the farthest corner ray.
    let reach = view.range * f64::from(longest) + 1.0;
    let mut targets: Vec<Target<'_>> = scene
        .view_solids(view.origin, reach, exclude)
        .into_iter()
        .filter_map(|solid| {
            let rect = project(&solid, o, f, r, d, (tan, tan_v), (w, h))?;
            let nearest = o.clamp(solid.aabb.mins, solid.aabb.maxs);
            let near = (nearest - o).length() / longest * (1.0 - 1e-5);
            let local = match &solid.shape {
                ViewShape::Cuboid {
                    centre, to_local, ..
                } => [
                    *to_local * (o - *centre),
                    *to_local * f,
                    *to_local * r,
                    *to_local * d,
                ],
                _ => [Vector::ZERO; 4],
            };
            Some(Target {
                solid,
                rect,
                near,
                local,
            })
        })
        .collect();
    // Nearest first (a stable sort: ties keep the tree's order, the same on every run).
    targets.sort_by(|a, b| a.near.total_cmp(&b.near));
    let mut which = vec![u32::MAX; n];
    let best = &mut image.depth;
    for (index, t) in targets.iter().enumerate() {
        let [x0, x1, y0, y1] = t.rect;
        for (y, &vy) in vs.iter().enumerate().take(y1).skip(y0) {
            let row = y * w;
            for (x, &ux) in us.iter().enumerate().take(x1).skip(x0) {
                let p = row + x;
                if best[p] <= t.near {
                    continue;
                }
                let hit = match &t.solid.shape {
                    ViewShape::Cuboid { half, .. } => {
                        let [lo, lf, lr, ld] = t.local;
                        slab(lo, lf + lr * ux + ld * vy, *half, best[p])
                    }
                    ViewShape::Cylinder {
                        centre,
                        radius,
                        half_height,
                    } => {
                        let ray = Ray::new(o, f + r * ux + d * vy);
                        upright_cylinder_toi(&ray, *centre, *radius, *half_height, best[p])
                            .filter(|&s| s < best[p])
                    }
                    ViewShape::Other(collider) => {
                        let ray = Ray::new(o, f + r * ux + d * vy);
                        collider
                            .shape()
                            .cast_ray(collider.position(), &ray, best[p], true)
                            .filter(|&s| s < best[p])
                    }
                };
                if let Some(s) = hit {
                    best[p] = s;
                    which[p] = index as u32;
                }
            }
        }
    }
    let light = v(LIGHT.map(f64::from)).normalize();
    for (y, &vy) in vs.iter().enumerate() {
        for (x, &ux) in us.iter().enumerate() {
            let p = y * w + x;
            let Some(t) = targets.get(which[p] as usize) else {
                image.depth[p] = f32::INFINITY;
                image.rgb[3 * p..3 * p + 3].copy_from_slice(&SKY);
                continue;
            };
            let dir = f + r * ux + d * vy;
            let s = image.depth[p];
            let normal = normal_at(&t.solid, o, dir, s);
            let lit = AMBIENT + DIFFUSE * (-normal.dot(light)).max(0.0);
            image.segment[p] = t.solid.look.segment;
            let Look { color, .. } = t.solid.look;
            for (out, &c) in image.rgb[3 * p..3 * p + 3].iter_mut().zip(&color) {
                *out = (f32::from(c) * lit).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
}

/// The pixel rectangle the solid's box may cover (`None`: none of it is in view).
fn project(
    solid: &ViewSolid<'_>,
    o: Vector,
    f: Vector,
    r: Vector,
    d: Vector,
    (tan, tan_v): (f32, f32),
    (w, h): (usize, usize),
) -> Option<[usize; 4]> {
    let (lo, hi) = (solid.aabb.mins, solid.aabb.maxs);
    let (mut u0, mut u1, mut v0, mut v1) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
    let mut behind = 0;
    for k in 0..8 {
        let c = Vector::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        ) - o;
        let depth = c.dot(f);
        if depth <= 1e-3 {
            behind += 1;
            continue;
        }
        let (u, v) = (c.dot(r) / depth, c.dot(d) / depth);
        u0 = u0.min(u);
        u1 = u1.max(u);
        v0 = v0.min(v);
        v1 = v1.max(v);
    }
    if behind == 8 {
        return None;
    }
    if behind > 0 {
        // The box reaches behind the camera: any pixel may see it.
        return Some([0, w, 0, h]);
    }
    // Pixel i's ray is at u = ((2i + 1) / w − 1)·tan; one pixel of slack for rounding.
    let span = |a: f32, b: f32, tan: f32, n: usize| -> Option<(usize, usize)> {
        let lo = ((a / tan + 1.0) * n as f32 / 2.0 - 1.0).floor().max(0.0);
        let hi = ((b / tan + 1.0) * n as f32 / 2.0 + 1.0)
            .ceil()
            .min(n as f32);
        (lo < hi).then_some((lo as usize, hi as usize))
    };
    let (x0, x1) = span(u0, u1, tan, w)?;
    let (y0, y1) = span(v0, v1, tan_v, h)?;
    Some([x0, x1, y0, y1])
}

/// The ray parameter at which a ray from `o` along `dir` (box frame) enters the box of half
/// extents `half` around the origin, if before `best` (0 when it starts inside).
fn slab(o: Vector, dir: Vector, half: Vector, best: f32) -> Option<f32> {
    let (mut t0, mut t1) = (0.0f32, best);
    for k in 0..3 {
        let (ok, dk, hk) = (o[k], dir[k], half[k]);
        if dk == 0.0 {
            if ok.abs() > hk {
                return None;
            }
            continue;
        }
        let inv = 1.0 / dk;
        let (a, b) = ((-hk - ok) * inv, (hk - ok) * inv);
        let (a, b) = if a < b { (a, b) } else { (b, a) };
        t0 = t0.max(a);
        t1 = t1.min(b);
        if t0 > t1 {
            return None;
        }
    }
    (t0 < best).then_some(t0)
}

/// The outward normal of `solid` where the ray from `o` along `dir` hits it at `s`.
fn normal_at(solid: &ViewSolid<'_>, o: Vector, dir: Vector, s: f32) -> Vector {
    let p = o + dir * s;
    match &solid.shape {
        ViewShape::Cuboid {
            centre,
            to_local,
            half,
        } => {
            let q = *to_local * (p - *centre);
            let ratio = (q / *half).abs();
            let k = if ratio.x >= ratio.y && ratio.x >= ratio.z {
                0
            } else if ratio.y >= ratio.z {
                1
            } else {
                2
            };
            let mut n = Vector::ZERO;
            n[k] = q[k].signum();
            to_local.inverse() * n
        }
        ViewShape::Cylinder {
            centre,
            radius,
            half_height,
        } => {
            let q = p - *centre;
            let side = (q.x * q.x + q.y * q.y).sqrt();
            if q.z.abs() / half_height >= side / radius {
                Vector::new(0.0, 0.0, q.z.signum())
            } else {
                Vector::new(q.x / side, q.y / side, 0.0)
            }
        }
        ViewShape::Other(collider) => {
            let ray = Ray::new(o, dir);
            collider
                .shape()
                .cast_ray_and_get_normal(collider.position(), &ray, s * 1.001 + 1e-4, true)
                .map_or(-dir.normalize(), |hit| {
                    // Seen from behind (a mesh face's back): the face turned to the camera.
                    if hit.normal.dot(dir) > 0.0 {
                        -hit.normal
                    } else {
                        hit.normal
                    }
                })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::direction;
    use rapier3d::math::Pose;
    use rapier3d::prelude::ColliderBuilder;

    /// A camera at `origin` looking along (pitch, yaw), level otherwise.
    fn view(origin: V3, pitch: f64, yaw: f64, fov_deg: f64, width: u32, height: u32) -> View {
        let forward = direction(pitch, yaw);
        let right = direction(0.0, yaw + std::f64::consts::FRAC_PI_2);
        let down = [
            forward[1] * right[2] - forward[2] * right[1],
            forward[2] * right[0] - forward[0] * right[2],
            forward[0] * right[1] - forward[1] * right[0],
        ];
        View {
            origin,
            forward,
            right,
            down,
            fov: fov_deg.to_radians(),
            width,
            height,
            range: 1000.0,
        }
    }

    fn wall_at(distance: f32) -> Scene {
        let mut scene = Scene::new();
        let wall = scene.insert(
            ColliderBuilder::cuboid(0.5, 50.0, 50.0).position(Pose::translation(
                distance + 0.5,
                0.0,
                0.0,
            )),
        );
        scene.set_look(
            wall,
            Look {
                color: [200, 100, 50],
                segment: 7,
            },
        );
        scene.refit();
        scene
    }

    #[test]
    fn a_plane_at_a_known_depth_fills_the_image_at_that_depth() {
        let scene = wall_at(2.0);
        let mut image = Image::default();
        render(
            &scene,
            &view([0.0; 3], 0.0, 0.0, 90.0, 64, 48),
            None,
            &mut image,
        );
        assert_eq!(
            (image.width, image.height, image.rgb.len()),
            (64, 48, 64 * 48 * 3)
        );
        for (p, &depth) in image.depth.iter().enumerate() {
            assert!((depth - 2.0).abs() < 1e-5, "pixel {p}: depth {depth}");
        }
        assert!(image.segment.iter().all(|&s| s == 7));
        // Lit from above, seen head-on: the face whose normal points at the camera gets
        // the ambient light and the sun's share along that normal.
        let lit = AMBIENT + DIFFUSE * (-(-1.0f32) * LIGHT[0] / norm(LIGHT)).max(0.0);
        let expect = [200.0, 100.0, 50.0].map(|c: f32| (c * lit).round() as u8);
        assert_eq!(&image.rgb[..3], &expect);
        assert!(image.rgb.chunks(3).all(|px| px == expect));
    }

    fn norm(v: [f32; 3]) -> f32 {
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
    }

    #[test]
    fn a_box_edge_falls_on_the_pixel_the_projection_says() {
        // A box from y = 1.25 east, 5 m ahead: at 90°, 64 pixels, its edge is at
        // u = 1.25 / 5 = 0.25, between the centres of pixels 39 (u = 0.234) and 40 (0.266).
        let mut scene = Scene::new();
        scene.insert(
            ColliderBuilder::cuboid(0.005, 5.0, 5.0).position(Pose::translation(5.005, 6.25, 0.0)),
        );
        scene.refit();
        let mut image = Image::default();
        render(
            &scene,
            &view([0.0; 3], 0.0, 0.0, 90.0, 64, 48),
            None,
            &mut image,
        );
        let row = 24 * 64;
        assert_eq!(image.depth[row + 39], f32::INFINITY);
        assert_eq!(&image.rgb[3 * (row + 39)..3 * (row + 40)], &SKY);
        assert!((image.depth[row + 40] - 5.0).abs() < 1e-5);
        // Above and below: the box is 10 m high (±5 m), always in view at this width.
        assert!((image.depth[40] - 5.0).abs() < 1e-5);
    }

    #[test]
    fn depths_equal_the_scenes_own_ray_casts_in_the_city() {
        let map = crate::Map::embedded("city").unwrap();
        let mut scene = Scene::new();
        map.build(&mut scene);
        scene.insert_body(
            crate::scene::BodyShape {
                radius: 0.45,
                half_height: 0.1,
            },
            [8.0, 1.0, -2.0],
        );
        scene.refit();
        for (origin, pitch, yaw) in [
            ([0.0, 0.0, -2.0], 0.0, 0.0),
            ([0.0, 0.0, -2.0], -0.3, 0.8),
            ([10.0, -20.0, -25.0], -0.6, -2.3),
            ([-5.0, 5.0, -1.0], 0.2, 3.0),
        ] {
            let v = view(origin, pitch, yaw, 80.0, 40, 30);
            let mut image = Image::default();
            render(&scene, &v, None, &mut image);
            let tan = (v.fov / 2.0).tan();
            let (mut hits, mut grazing) = (0, 0);
            for j in 0..30 {
                for i in 0..40 {
                    let u = ((2 * i + 1) as f64 / 40.0 - 1.0) * tan;
                    let w = ((2 * j + 1) as f64 / 30.0 - 1.0) * tan * 0.75;
                    let dir: V3 =
                        std::array::from_fn(|k| v.forward[k] + u * v.right[k] + w * v.down[k]);
                    let len = dir.iter().map(|x| x * x).sum::<f64>().sqrt();
                    let unit = dir.map(|x| x / len);
                    let cast = scene.cast_ray(origin, unit, 1000.0 * len, None);
                    let depth = f64::from(image.depth[j * 40 + i]);
                    let cast = cast.map_or(f64::INFINITY, |s| s / len);
                    hits += usize::from(cast.is_finite());
                    // A ray along an edge may hit in f64 and miss in f32, or the reverse.
                    if !((cast - depth).abs() < 2e-3 * (1.0 + depth) || cast == depth) {
                        grazing += 1;
                    }
                }
            }
            assert!(
                grazing <= 6,
                "view {origin:?}: {grazing} of 1200 pixels disagree"
            );
            assert!(hits > 100, "{hits}");
        }
    }
}
