//! The collision geometry: map solids and robot bodies in rapier's collider set, indexed by a
//! BVH that is updated the moment a robot moves, so every query sees the current positions.
//!
//! Frame: the protocol frame everywhere (x forward/north, y right/east, z down, metres).
//!
//! Why no `PhysicsPipeline::step`: nothing in this world is dynamic (robots are kinematic,
//! gravity is off, UDK imposes their velocity directly), so a physics step would only update
//! the broad phase once per tick — after all robots moved, letting two robots step into each
//! other within one tick. Instead each robot is swept with a shape cast and its BVH leaf is
//! refreshed immediately; queries run through rapier's `QueryPipeline` over that BVH.

use std::collections::HashMap;

use crate::upright::Pair;
use rapier3d::math::{Pose, Rotation, Vector};
use rapier3d::parry::bounding_volume::Aabb;
use rapier3d::parry::math::Real;
use rapier3d::parry::partitioning::{Bvh, BvhNode, BvhWorkspace};
use rapier3d::parry::query::{
    ClosestPoints, Contact, DefaultQueryDispatcher, NonlinearRigidMotion, QueryDispatcher,
    ShapeCastHit, ShapeCastOptions, ShapeCastStatus, ShapeDistance, ShapeIntersection, Unsupported,
};
use rapier3d::parry::shape::{Cuboid, Cylinder, Shape};
use rapier3d::prelude::{
    Collider, ColliderHandle, ColliderSet, IslandManager, QueryFilter, QueryPipeline, Ray,
    RigidBodySet, SoftBodySet,
};

/// A plain f64 vector in the protocol frame.
pub(crate) type V3 = [f64; 3];

/// Metres: every coordinate and size in a map (and every robot position) lies within
/// ±`LIMIT` of the origin on each axis. The world ends there: no motion goes further
/// (`Scene::sweep`); f32 (the physics' precision) still resolves centimetres at this
/// distance.
pub const LIMIT: f64 = 100_000.0;

/// Least extra room (m) around a robot's BVH leaf so small moves do not touch the tree.
const LEAF_MARGIN: f32 = 0.05;

/// The room around `leaf`'s new box `aabb`: between [`LEAF_MARGIN`] and twice that, drawn
/// from the leaf and where its box is (a hash, so the same at any thread count). Robots that
/// move together (a swarm on one command, a benchmark's grid) then leave their boxes on
/// different ticks instead of all on one, which made a crowd's longest tick twice its median
/// (issue 27's tail). A room the same for every box (or the same for each leaf) puts the
/// places where a robot leaves its box on a grid from its start, so robots flying out and
/// back all left their boxes together when home again.
fn leaf_margin(leaf: u32, aabb: &Aabb) -> f32 {
    let [x, y, z] = [aabb.mins.x, aabb.mins.y, aabb.mins.z].map(|c| u64::from(c.to_bits()));
    let mut seed = u64::from(leaf) ^ (x << 32) ^ (y << 16) ^ z;
    let spread = (crate::noise::splitmix(&mut seed) >> 40) as f32;
    LEAF_MARGIN * (1.0 + spread / (1u64 << 24) as f32)
}

/// Gap (m) kept between a swept robot and what it hits.
const SKIN: f32 = 0.01;
/// Beyond this distance (m) between tree boxes a sweep cannot touch: the gap `SKIN`,
/// doubled for rounding.
const SWEEP_PAD: f32 = 2.0 * SKIN + 1e-4;
/// Longest sweep per tick (m): keeps f32 times of impact precise at absurd speeds.
const MAX_STEP: f64 = 100.0;
/// A slide shorter than this fraction of the blocked motion is numerical noise of the
/// contact normal, not a real glancing contact: dropped so a robot pushing straight into a
/// wall does not creep sideways.
const MIN_SLIDE: f64 = 0.05;

/// Rotates `v` by `yaw` about the vertical axis (positive = clockwise seen from above).
pub(crate) fn yaw_rotate(yaw: f64, v: V3) -> V3 {
    let (s, c) = yaw.sin_cos();
    rotate_by(s, c, v)
}

/// [`yaw_rotate`] by the yaw whose sine and cosine are `s` and `c`.
pub(crate) fn rotate_by(s: f64, c: f64, v: V3) -> V3 {
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

/// The unit vector of a (pitch, yaw) direction; positive pitch points up (−z).
pub(crate) fn direction(pitch: f64, yaw: f64) -> V3 {
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    [cp * cy, cp * sy, -sp]
}

pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(crate) fn scale(a: V3, k: f64) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: V3) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// `norm(a).partial_cmp(&limit)` for a `limit` > 0, with the square root taken only when
/// the squared length is within a factor 4 of `limit`'s square (the same answer: the root
/// is monotonic; a sweep asked two such questions of every move).
fn compare_norm(a: V3, limit: f64) -> Option<std::cmp::Ordering> {
    let squared = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
    let limit_squared = limit * limit;
    if squared < 0.25 * limit_squared {
        Some(std::cmp::Ordering::Less)
    } else if squared > 4.0 * limit_squared {
        Some(std::cmp::Ordering::Greater)
    } else {
        squared.sqrt().partial_cmp(&limit)
    }
}

fn to_vector(v: V3) -> Vector {
    Vector::new(v[0] as f32, v[1] as f32, v[2] as f32)
}

/// A robot's collision shape: a vertical cylinder, so that turning never makes it overlap.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BodyShape {
    pub(crate) radius: f64,
    pub(crate) half_height: f64,
}

impl BodyShape {
    fn cylinder(self) -> Cylinder {
        Cylinder::new(self.half_height as f32, self.radius as f32)
    }
}

/// parry cylinders stand along y; this turns them upright along z: a quarter turn about x,
/// as `Rotation::from_rotation_x(FRAC_PI_2)` makes it (without its sine and cosine at every
/// cast).
const UPRIGHT: Rotation = Rotation::from_xyzw(
    std::f32::consts::FRAC_1_SQRT_2,
    0.0,
    0.0,
    std::f32::consts::FRAC_1_SQRT_2,
);

/// The pose of an upright cylinder centred at `centre`.
pub(crate) fn upright_pose(centre: V3) -> Pose {
    Pose::from_parts(to_vector(centre), UPRIGHT)
}

thread_local! {
    /// Scratch space for [`Scene::refit`], one per thread (its contents never outlive a refit).
    static WORKSPACE: std::cell::RefCell<BvhWorkspace> = std::cell::RefCell::default();
}

/// The world geometry and the robots' bodies.
#[derive(Clone)]
pub(crate) struct Scene {
    colliders: ColliderSet,
    bodies: RigidBodySet,
    islands: IslandManager,
    soft_bodies: SoftBodySet,
    bvh: Bvh,
    /// Batched ray casts and skipped sweeps (off: one tree walk per ray and a shape cast per
    /// move, the reference they must equal bit for bit).
    pub(crate) shortcuts: bool,
    /// Leaves were added or removed since the last refit (see [`Scene::refresh`]).
    stale: bool,
    /// By leaf: what is known of the room around its tree box ([`Room`]).
    clear: Vec<Room>,
    /// By leaf: the robot's last sweep, when it left the robot where it was, pressed
    /// against one map solid ([`Rest`]). A map, not a vector by leaf: few robots rest, and
    /// a lookup that finds nothing then touches no memory of its own (a vector by leaf cost
    /// 10,000 hovering robots 40 % of their tick in cache misses).
    resting: HashMap<u32, Rest>,
    /// By leaf: how cameras draw the solid (colour, segmentation id); [`Look::default`]
    /// for solids without one.
    looks: Vec<Look>,
    /// A collider was removed since the scene was built or last reset ([`Scene::reset`]
    /// then copies the scene it was copied from whole).
    removed: bool,
    /// The map's victims: their colliders and boxes (the VictSensor's targets).
    pub(crate) victims: Vec<VictimBody>,
    /// Where the map is on the Earth (the GPS's origin, the magnetometer's field).
    pub(crate) geo: crate::map::GeoConfig,
    /// The scene this one was copied from (the map's, shared by the worlds of the map):
    /// its colliders, the map's, are this scene's first ones, and queries read them there —
    /// one copy in the caches for a thousand worlds ([`Scene::collider_at`]).
    base: Option<std::sync::Arc<Self>>,
    /// Robot bodies in the scene: with exactly one, its sweeps read the solids near it
    /// from its [`Plan`] instead of the tree.
    body_count: usize,
    /// The solids near the scene's only robot ([`Scene::plan_for`]).
    plan: Option<Plan>,
    /// A [`Glide`]'s solids between glides (kept allocated).
    glide_near: Vec<Near>,
    /// Robot bodies a reset kept in the collider set, out of the tree, highest index first:
    /// the next bodies of their shape take them back ([`Scene::insert_body`]).
    parked: Vec<ColliderHandle>,
}

/// The tree leaves near the scene's only robot body, learnt by one tree query over a
/// region around it and kept while its sweeps stay inside that region: a sweep asks the
/// tree for the leaves whose boxes meet its padded swept box, and inside the region those
/// are exactly the plan's leaves whose boxes meet it, in the tree's order (no other leaf
/// moves, is added or leaves while the plan is kept: anything added or removed drops it;
/// a refit changes neither the solids' boxes nor the tree's order).
#[derive(Debug, Clone)]
struct Plan {
    /// The robot's leaf.
    leaf: u32,
    /// The region the plan knows.
    region: Aabb,
    /// The other leaves whose boxes meet the region, in the tree's order.
    near: Vec<Near>,
    /// The robot's own leaf as the tree holds it (kept by [`Scene::place_leaf`]).
    mine: Option<BvhNode>,
}

/// A leaf of a [`Plan`]: its tree box, and what a cast against it reads of its collider
/// (`None` when that is not a box upright to the robot: the sweep then casts as usual).
#[derive(Debug, Clone)]
struct Near {
    node: BvhNode,
    solid: Option<Solid>,
}

/// A box collider upright to the robots, as a cast in closed form reads it (a [`Plan`]
/// keeps them: no lookups or shape dispatch at each cast).
#[derive(Debug, Clone, Copy)]
struct Solid {
    handle: ColliderHandle,
    pose: Pose,
    cuboid: Cuboid,
    /// The box is not rotated (a map's walls, floors and ceilings): [`Solid::resting`].
    level: bool,
}

impl Solid {
    /// `None` when the collider is not a box, or a robot does not stand upright in its frame
    /// (a robot's rotation is the same wherever it is).
    fn of(collider: &Collider, handle: ColliderHandle) -> Option<Self> {
        let pose = *collider.position();
        let cuboid = *collider.shape().as_cuboid()?;
        is_upright(&pose.inv_mul(&upright_pose([0.0; 3]))).then_some(Self {
            handle,
            pose,
            cuboid,
            level: pose.rotation == Rotation::IDENTITY,
        })
    }

    /// The cylinder at `body` moving by `vel` against this box: the closed form's time and
    /// normal, turned into the world's frame as parry's `transform1_by` turns a hit (the
    /// sweep reads nothing else of it).
    fn impact(
        &self,
        body: &Pose,
        vel: Vector,
        cylinder: &Cylinder,
        options: ShapeCastOptions,
    ) -> Option<Impact> {
        match self.resting(body, vel, cylinder, options) {
            Some(impact) => impact,
            None => self.full_impact(body, vel, cylinder, options),
        }
    }

    /// [`Solid::impact`] by the closed form's full cast in the box's frame.
    fn full_impact(
        &self,
        body: &Pose,
        vel: Vector,
        cylinder: &Cylinder,
        options: ShapeCastOptions,
    ) -> Option<Impact> {
        let pose = &self.pose;
        let hit = upright_hit(
            &pose.inv_mul(body),
            pose.rotation.inverse() * vel,
            &self.cuboid,
            cylinder,
            options,
        )?;
        let n = hit.normal.map(|x| x as Real);
        Some(Impact {
            solid: self.handle,
            toi: hit.toi as Real,
            normal: pose.rotation * Vector::new(n[0], n[1], n[2]),
        })
    }

    /// [`Solid::impact`] without turning the body into the box's frame and back, for the
    /// cast most sweeps of a robot on a floor or under a ceiling make: a level box, the body
    /// over (or under) its top (bottom) face and already within the target distance of it.
    /// The closed form then decides at the start from the vertical gap alone
    /// ([`crate::upright::Pair::cast`]: the separation is `(0, 0, z)`, the normal
    /// `(0, 0, z / |z|)`, a hit at time 0 when the motion goes into the face), and an
    /// unrotated frame changes no non-zero coordinate of the body or its motion (a
    /// quaternion with zero vector part multiplies them by exactly one), so every number is
    /// the one the full cast computes. `None` when it does not apply (the full cast then).
    fn resting(
        &self,
        body: &Pose,
        vel: Vector,
        cylinder: &Cylinder,
        options: ShapeCastOptions,
    ) -> Option<Option<Impact>> {
        if !self.level {
            return None;
        }
        let c = body.translation - self.pose.translation;
        let h = self.cuboid.half_extents;
        // Over the face: no horizontal separation (the rim's cases take the full cast).
        if !(c.x.abs() <= h.x && c.y.abs() <= h.y) {
            return None;
        }
        let cz = f64::from(c.z);
        let z = (cz.abs() - (f64::from(h.z) + f64::from(cylinder.half_height))).max(0.0);
        let z = z.copysign(cz);
        let start = (z * z).sqrt();
        // Overlapping (no gap: the way out depends on more than z) or not yet within.
        if !(start > 0.0 && start <= f64::from(options.target_distance)) {
            return None;
        }
        let normal = z / start;
        // The dot product of the normal (0, 0, normal) with the motion, whose horizontal
        // terms are zeros.
        Some((normal * f64::from(vel.z) < 0.0).then(|| Impact {
            solid: self.handle,
            toi: 0.0,
            normal: self.pose.rotation * Vector::new(0.0, 0.0, normal as Real),
        }))
    }
}

impl Plan {
    /// Whether the plan answers for the leaf `me` a sweep whose padded swept box is `query`.
    fn covers(&self, me: u32, query: &Aabb) -> bool {
        self.leaf == me
            && self.region.mins.cmple(query.mins).all()
            && query.maxs.cmple(self.region.maxs).all()
    }
}

/// Metres of room a [`Plan`] learns around the sweep that made it: a robot flying at 2 m/s
/// along one axis leaves it after a quarter of a second (50 ticks), one at every maximum
/// speed at once (about 3.5 m/s) after 0.14 s.
const PLAN_ROOM: f32 = 0.5;

/// What a leaf's entry in [`Scene`]'s `clear` knows of the room around the leaf's tree box.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
enum Room {
    /// Nothing known: the next sweep that stays inside the box asks the tree.
    #[default]
    Unknown,
    /// No other leaf's box comes within `SWEEP_PAD` of this one (kept only while that holds:
    /// any leaf box that grows makes the leaves near it `Unknown`). A robot whose motion
    /// stays inside its own box then moves without a tree query or a shape cast.
    Clear,
    /// Another leaf's box came within `SWEEP_PAD` (a robot beside a wall or on the floor):
    /// its sweeps cast without asking again. Possibly stale when the other leaf moved away
    /// or left, which costs casts, not results; every refit forgets it.
    Crowded,
}

/// A sweep that left its robot where it was, pressed against one map solid: a UAV landed
/// with a descending set point, one leaning on a wall. The sweep is a function of the start,
/// the motion, the robot's shape and the colliders near it; while the same motion starts
/// from the same place (bit for bit) and nothing but that solid (which never moves) is near,
/// its answer is the same, and it is not cast again: landed UAVs cost a tree query a tick,
/// not GJK contact queries.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rest {
    centre: V3,
    motion: V3,
    /// The solid's leaf.
    solid: u32,
    /// The contact normal the sweep reported.
    normal: V3,
}

/// `Collider::user_data` of the map's solids (walls for the robot monitor's count).
const WALL: u128 = 0;
/// `Collider::user_data` of a robot body.
const BODY: u128 = 1;
/// `Collider::user_data` of a victim.
const VICTIM: u128 = 2;

/// A victim's body in the scene: a box (`Placed` of the map).
#[derive(Debug, Clone)]
pub(crate) struct VictimBody {
    pub(crate) handle: ColliderHandle,
    pub(crate) center: V3,
    pub(crate) size: V3,
    pub(crate) yaw: f64,
}

/// How a camera draws a solid: its colour (before shading) and its segmentation id.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Look {
    /// sRGB colour of a surface lit head-on.
    pub(crate) color: [u8; 3],
    /// Segmentation id (0 is the sky: nothing hit).
    pub(crate) segment: u32,
}

impl Default for Look {
    fn default() -> Self {
        Self {
            color: [160, 160, 160],
            segment: 0,
        }
    }
}

/// A solid as a camera sees it ([`Scene::view_solids`]).
pub(crate) struct ViewSolid<'s> {
    pub(crate) shape: ViewShape<'s>,
    /// Its box (world frame).
    pub(crate) aabb: Aabb,
    pub(crate) look: Look,
}

/// The shapes a camera intersects in closed form, and the rest.
pub(crate) enum ViewShape<'s> {
    /// A box: centre, the rotation from world to box frame, half extents.
    Cuboid {
        centre: Vector,
        to_local: Rotation,
        half: Vector,
    },
    /// An upright cylinder (robots, pillars).
    Cylinder {
        centre: Vector,
        radius: f32,
        half_height: f32,
    },
    /// Anything else (meshes): parry's ray casts.
    Other(&'s Collider),
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("colliders", &self.colliders.len())
            .finish_non_exhaustive()
    }
}

impl Scene {
    pub(crate) fn new() -> Self {
        Self {
            colliders: ColliderSet::new(),
            bodies: RigidBodySet::new(),
            islands: IslandManager::new(),
            soft_bodies: SoftBodySet::new(),
            bvh: Bvh::new(),
            shortcuts: true,
            stale: false,
            clear: Vec::new(),
            resting: HashMap::new(),
            looks: Vec::new(),
            removed: false,
            victims: Vec::new(),
            geo: crate::map::GeoConfig::default(),
            base: None,
            body_count: 0,
            plan: None,
            glide_near: Vec::new(),
            parked: Vec::new(),
        }
    }

    /// A copy of the map's scene `base` that reads the map's colliders in `base`.
    pub(crate) fn copy_of(base: &std::sync::Arc<Self>) -> Self {
        Self {
            base: Some(base.clone()),
            ..(**base).clone()
        }
    }

    /// The collider at tree leaf `leaf`: a map solid's in the scene copied from (the same
    /// collider: map solids never move or leave), any other in this one.
    fn collider_at(&self, leaf: u32) -> Option<(&Collider, ColliderHandle)> {
        match &self.base {
            Some(base) if (leaf as usize) < base.colliders.len() => {
                base.colliders.get_unknown_gen(leaf)
            }
            _ => self.colliders.get_unknown_gen(leaf),
        }
    }

    /// [`crate::World::prefetch`]'s part: the solids near the only robot ([`Plan`]).
    pub(crate) fn prefetch(&self) {
        if let Some(plan) = &self.plan {
            crate::prefetch::lines(&plan.near, 4);
        }
    }

    /// [`crate::World::prefetch_early`]'s part: where the plan is.
    pub(crate) fn prefetch_early(&self) {
        crate::prefetch::line(&self.plan);
    }

    /// [`crate::World::prefetch_reset`]'s part: what [`Scene::reset`] and the next bodies'
    /// insertion write (the scene's own fields, its small tables, the colliders of
    /// `bodies`, the robots' bodies it parks).
    pub(crate) fn prefetch_reset(&self, bodies: impl Iterator<Item = ColliderHandle>) {
        use crate::prefetch::{line, lines};
        line(&self.colliders);
        line(&self.bvh);
        line(&self.clear);
        line(&self.resting);
        line(&self.base);
        line(&self.plan);
        line(&self.glide_near);
        line(&self.parked);
        lines(&self.clear, 2);
        lines(&self.looks, 2);
        lines(&self.parked, 1);
        for handle in bodies {
            if let Some(c) = self.colliders.get(handle) {
                line(c);
                line(c.position());
            }
        }
    }

    /// Becomes the scene it was copied from again ([`Scene::copy_of`]: the map as first
    /// built, before any robot) when it is that scene plus the robot `bodies` inserted since:
    /// their colliders are parked (out of the tree; the next bodies of their shape take them
    /// back, lowest index first, and the rest are removed, highest first, before any other
    /// insertion: the indices, the tree leaves, a new copy would give), and the tree and the
    /// small tables are copied. Every query then answers as on a new copy, bit for bit, without
    /// copying the map's colliders (most of a Python reset's cost). Otherwise (a robot left
    /// meanwhile) a new copy. A scene not copied from another is left as it is.
    pub(crate) fn reset(&mut self, bodies: &mut [ColliderHandle]) {
        // Taken out and put back, not cloned: every world of a batch shares the template,
        // and two threads counting references to it in turn kept taking its cache line
        // from each other (2.6 % of the samples of a loop of resetting and normal steps).
        let Some(template) = self.base.take() else {
            return;
        };
        self.drop_parked();
        if self.removed || self.colliders.len() != template.colliders.len() + bodies.len() {
            *self = Self::copy_of(&template);
            return;
        }
        bodies.sort_unstable_by_key(|h| std::cmp::Reverse(h.into_raw_parts().0));
        self.parked.clear();
        self.parked.extend_from_slice(bodies);
        self.bvh.clone_from(&template.bvh);
        self.shortcuts = template.shortcuts;
        self.stale = template.stale;
        self.clear.clone_from(&template.clear);
        self.resting.clone_from(&template.resting);
        self.looks.clone_from(&template.looks);
        self.removed = false;
        self.victims.clone_from(&template.victims);
        self.body_count = template.body_count;
        self.plan = None;
        self.base = Some(template);
    }

    /// Marks the collider `handle` (already inserted) as a victim's body: a box centred at
    /// `center`, of full extents `size` before the `yaw` (a map's `Placed` victim).
    pub(crate) fn add_victim(&mut self, handle: ColliderHandle, center: V3, size: V3, yaw: f64) {
        if let Some(c) = self.colliders.get_mut(handle) {
            c.user_data = VICTIM;
        }
        self.victims.push(VictimBody {
            handle,
            center,
            size,
            yaw,
        });
    }

    /// Whether `collider` (not in the scene) meets any solid of the scene.
    pub(crate) fn box_overlaps(&self, collider: &Collider) -> bool {
        self.query(None)
            .intersect_shape(*collider.position(), collider.shape())
            .next()
            .is_some()
    }

    /// [`Scene::cast_ray`] that also names what the ray hit.
    pub(crate) fn cast_ray_hit(
        &self,
        origin: V3,
        dir: V3,
        max: f64,
        exclude: Option<ColliderHandle>,
    ) -> Option<(f64, ColliderHandle)> {
        let ray = Ray::new(to_vector(origin), to_vector(dir));
        let skip = exclude.map(|h| h.into_raw_parts().0);
        self.bvh
            .cast_ray(&ray, max as f32, |leaf, best| {
                if Some(leaf) == skip {
                    return None;
                }
                let (collider, _) = self.collider_at(leaf)?;
                leaf_toi(collider, &ray, best)
            })
            .and_then(|(leaf, toi)| {
                let (_, handle) = self.collider_at(leaf)?;
                Some((f64::from(toi), handle))
            })
    }

    /// Walls between `a` and `b` as USARSim's robot monitor counts them (side-servers.md
    /// §3.2): a ray from `a` to `b`, restarted 0.2 m past each hit; a hit on a solid of
    /// the map (not a robot, not a victim) counts if it is another solid than the last one
    /// counted or lies more than 0.2 m from the restart point (a thick wall counts once).
    pub(crate) fn obstacles_between(&self, a: V3, b: V3) -> u32 {
        const STEP: f64 = 0.2;
        let d = sub(b, a);
        let length = norm(d);
        if length.is_nan() || length <= 1e-9 {
            return 0;
        }
        let dir = scale(d, 1.0 / length);
        let (mut from, mut count, mut last) = (0.0, 0u32, None);
        // At most one hit per 0.2 m (bounded work for any distance within the world).
        while from < length && count < 100_000 {
            let origin = add(a, scale(dir, from));
            let Some((toi, handle)) = self.cast_ray_hit(origin, dir, length - from, None) else {
                break;
            };
            let wall = self
                .colliders
                .get(handle)
                .is_some_and(|c| c.user_data == WALL);
            if wall && (last != Some(handle) || toi > STEP) {
                count += 1;
                last = Some(handle);
            }
            from += toi + STEP;
        }
        count
    }

    /// Sets how cameras draw the solid `handle` (kept until it is removed).
    pub(crate) fn set_look(&mut self, handle: ColliderHandle, look: Look) {
        let i = handle.into_raw_parts().0 as usize;
        if i >= self.looks.len() {
            self.looks.resize(i + 1, Look::default());
        }
        self.looks[i] = look;
    }

    /// Every solid but `exclude` whose tree box meets the box of half size `reach` around
    /// `origin`, with its look: what a camera there may see (one tree query per frame).
    pub(crate) fn view_solids(
        &self,
        origin: V3,
        reach: f64,
        exclude: Option<ColliderHandle>,
    ) -> Vec<ViewSolid<'_>> {
        let o = to_vector(origin);
        let r = Vector::splat(reach as f32);
        let skip = exclude.map(|h| h.into_raw_parts().0);
        self.bvh
            .intersect_aabb(&Aabb::new(o - r, o + r))
            .filter(|&leaf| Some(leaf) != skip)
            .filter_map(|leaf| {
                let (collider, _) = self.collider_at(leaf)?;
                let look = self.looks.get(leaf as usize).copied().unwrap_or_default();
                let pose = collider.position();
                let shape = if let Some(c) = collider.shape().as_cylinder() {
                    ViewShape::Cylinder {
                        centre: collider.translation(),
                        radius: c.radius,
                        half_height: c.half_height,
                    }
                } else if let Some(c) = collider.shape().as_cuboid() {
                    ViewShape::Cuboid {
                        centre: pose.translation,
                        to_local: pose.rotation.inverse(),
                        half: c.half_extents,
                    }
                } else {
                    ViewShape::Other(collider)
                };
                Some(ViewSolid {
                    shape,
                    aabb: collider.compute_aabb(),
                    look,
                })
            })
            .collect()
    }

    /// Adds a collider (static solid or robot body) and indexes it.
    pub(crate) fn insert(&mut self, collider: impl Into<Collider>) -> ColliderHandle {
        self.drop_parked();
        let collider = collider.into();
        self.body_count += usize::from(collider.user_data == BODY);
        self.plan = None;
        let handle = self.colliders.insert(collider);
        self.reindex(handle);
        handle
    }

    /// Adds a robot body at `centre`: the first parked body when it has this shape (its
    /// collider moved there, as a new one would be), else a new collider.
    pub(crate) fn insert_body(&mut self, shape: BodyShape, centre: V3) -> ColliderHandle {
        if let Some(&handle) = self.parked.last()
            && let Some(collider) = self.colliders.get_mut(handle)
            && collider.shape().as_cylinder() == Some(&shape.cylinder())
        {
            self.parked.pop();
            collider.set_position(upright_pose(centre));
            self.body_count += 1;
            self.plan = None;
            self.reindex(handle);
            return handle;
        }
        let collider = rapier3d::prelude::ColliderBuilder::new(
            rapier3d::prelude::SharedShape::new(shape.cylinder()),
        )
        .position(upright_pose(centre))
        .user_data(BODY)
        .build();
        self.insert(collider)
    }

    /// A body's collider centre and tree box (min and max corners); NaN for what is missing.
    #[cfg(test)]
    pub(crate) fn body_box(&self, handle: ColliderHandle) -> [[f32; 3]; 3] {
        let xyz = |v: Vector| [v.x, v.y, v.z];
        let centre = self.colliders.get(handle).map(|c| xyz(c.translation()));
        let aabb = self
            .bvh
            .leaf_node(handle.into_raw_parts().0)
            .map(|n| n.aabb());
        [
            centre.unwrap_or([f32::NAN; 3]),
            aabb.map_or([f32::NAN; 3], |b| xyz(b.mins)),
            aabb.map_or([f32::NAN; 3], |b| xyz(b.maxs)),
        ]
    }

    /// Takes the parked bodies ([`Scene::reset`]) out of the collider set, highest index
    /// first, so that new colliders get the indices they would get in a new copy.
    fn drop_parked(&mut self) {
        if self.parked.is_empty() {
            return;
        }
        for body in self.parked.drain(..) {
            self.colliders.remove(
                body,
                &mut self.islands,
                &mut self.bodies,
                &mut self.soft_bodies,
                false,
            );
        }
        // rapier's change lists, kept for a physics pipeline this scene never runs.
        drop(self.colliders.take_modified());
        drop(self.colliders.take_removed());
    }

    /// Removes a collider.
    pub(crate) fn remove(&mut self, handle: ColliderHandle) {
        self.removed = true;
        self.plan = None;
        if self
            .colliders
            .get(handle)
            .is_some_and(|c| c.user_data == BODY)
        {
            self.body_count -= 1;
        }
        let leaf = handle.into_raw_parts().0;
        self.bvh.remove(leaf);
        self.set_clear(leaf, Room::Unknown);
        self.resting.remove(&leaf);
        if let Some(look) = self.looks.get_mut(leaf as usize) {
            *look = Look::default();
        }
        self.stale = true;
        self.colliders.remove(
            handle,
            &mut self.islands,
            &mut self.bodies,
            &mut self.soft_bodies,
            false,
        );
    }

    fn reindex(&mut self, handle: ColliderHandle) {
        if let Some(collider) = self.colliders.get(handle) {
            // Upright cylinders (every robot, every tick it moves) get their box in closed
            // form; parry would build it from six support points.
            let aabb = match collider.shape().as_cylinder() {
                Some(c) => {
                    let half = Vector::new(c.radius, c.radius, c.half_height);
                    let centre = collider.translation();
                    Aabb::new(centre - half, centre + half)
                }
                None => collider.compute_aabb(),
            };
            let body = collider.user_data == BODY;
            self.place_leaf(handle.into_raw_parts().0, aabb, body);
        }
    }

    /// Puts the leaf `leaf` (a `body` or not) in the tree with the box `aabb`, or grows its
    /// tree box (with a margin) when `aabb` left it.
    fn place_leaf(&mut self, leaf: u32, aabb: Aabb, body: bool) {
        let fat = || {
            let margin = Vector::splat(leaf_margin(leaf, &aabb));
            Aabb::new(aabb.mins - margin, aabb.maxs + margin)
        };
        match self.bvh.leaf_node(leaf) {
            Some(node) if node.contains_aabb(&aabb) => {}
            Some(_) => {
                // The leaf grows to the box with its margin, and so do its ancestors.
                // (parry's `insert_with_change_detection` with a margin widens the
                // ancestors only to the bare box: the robot could then drift out of
                // them, within its leaf, and tree walks missed it until a refit.)
                let fat = fat();
                let _ = self.bvh.insert_with_change_detection(fat, leaf, 0.0);
                if let Some(plan) = self.plan.as_mut().filter(|p| p.leaf == leaf) {
                    plan.mine = self.bvh.leaf_node(leaf).copied();
                }
                if body && self.lone() {
                    // The only robot: no other leaf's room is ever asked about.
                    self.set_clear(leaf, Room::Unknown);
                } else {
                    self.unclear_near(leaf, &fat);
                }
            }
            None => {
                // A robot's body starts with its margin (with the bare box, every robot
                // spawned together left it on the first tick it moved, all at once);
                // map solids never move and keep the bare box.
                let aabb = if body { fat() } else { aabb };
                self.bvh.insert(aabb, leaf);
                if body && self.lone() {
                    // The only robot (a Python world's, at each reset): no room is asked
                    // about while it is alone, and a second body's arrival forgets the
                    // rooms near it.
                    self.set_clear(leaf, Room::Unknown);
                } else {
                    self.unclear_near(leaf, &aabb);
                }
                self.stale = true;
            }
        }
    }

    /// Tightens the BVH (leaf updates only ever grow their ancestors). Call now and then.
    pub(crate) fn refit(&mut self) {
        // The refit's scratch tree is the thread's: it swaps buffers with the scene's, so
        // the one it writes is one the thread just used, not a cold one of this world's.
        WORKSPACE.with_borrow_mut(|workspace| self.bvh.refit(workspace));
        self.stale = false;
        for room in &mut self.clear {
            if *room == Room::Crowded {
                *room = Room::Unknown;
            }
        }
    }

    /// Keeps a leaf of the tree for the next collider, a first robot's body (a Python world's
    /// lone UAV at every reset, a server's first robot), far outside the world where no query
    /// meets it: the body then moves into it (one leaf's box updated in place) instead of
    /// being inserted, so that neither a new copy of the scene nor a reset one has a leaf to
    /// insert, arrays to grow or a tree to refit before its first tick.
    pub(crate) fn reserve_leaf(&mut self) {
        let leaf = u32::try_from(self.colliders.len()).unwrap_or(u32::MAX);
        if self.bvh.is_empty() || self.bvh.leaf_node(leaf).is_some() {
            return;
        }
        let far = Vector::new(0.0, 0.0, (4.0 * LIMIT) as f32);
        self.bvh.insert(Aabb::new(far, far), leaf);
        self.refit();
    }

    /// Refits the tree if leaves were added or removed since the last refit (insertions
    /// rotate subtrees; a refit leaves every inner box tight and right). Called at the
    /// start of each tick.
    pub(crate) fn refresh(&mut self) {
        if self.stale {
            self.refit();
        }
    }

    fn query(&self, exclude: Option<ColliderHandle>) -> QueryPipeline<'_> {
        let filter = QueryFilter {
            exclude_collider: exclude,
            ..QueryFilter::default()
        };
        QueryPipeline {
            dispatcher: &DefaultQueryDispatcher,
            bvh: &self.bvh,
            bodies: &self.bodies,
            colliders: &self.colliders,
            filter,
        }
    }

    /// [`Scene::query`] for sweeps: boxes are cut down to the part near the moving body
    /// ([`NearBoxes`]).
    fn sweep_query(&self, exclude: Option<ColliderHandle>) -> QueryPipeline<'_> {
        QueryPipeline {
            dispatcher: &NearBoxes,
            ..self.query(exclude)
        }
    }

    /// Distance along the unit vector `dir` from `origin` to the first surface within
    /// `max`, ignoring the collider `exclude` (the sensor's own robot).
    ///
    /// Ray casts dominate the server's cost. parry casts rays on cylinders (every robot
    /// body) with GJK, which a profile of 200 robots showed taking over 70% of the time, so
    /// upright cylinders — the only kind the scene holds — are intersected in closed form
    /// here; other shapes use parry's own ray casts.
    pub(crate) fn cast_ray(
        &self,
        origin: V3,
        dir: V3,
        max: f64,
        exclude: Option<ColliderHandle>,
    ) -> Option<f64> {
        let ray = Ray::new(to_vector(origin), to_vector(dir));
        let skip = exclude.map(|h| h.into_raw_parts().0);
        self.bvh
            .cast_ray(&ray, max as f32, |leaf, best| {
                if Some(leaf) == skip {
                    return None;
                }
                let (collider, _) = self.collider_at(leaf)?;
                leaf_toi(collider, &ray, best)
            })
            .map(|(_, toi)| f64::from(toi))
    }

    /// Gathers, once, every solid (but `exclude`) whose BVH box meets the box spanned by
    /// `origin` and `ends` (the far ends of the rays to come): one tree query instead of a
    /// tree walk per ray. [`RayBatch::cast`] and [`RayBatch::cast_fan`] then give exactly
    /// what [`Scene::cast_ray`] gives for rays from `origin` whose segments lie in that box.
    pub(crate) fn ray_batch(
        &self,
        origin: V3,
        ends: impl IntoIterator<Item = V3>,
        exclude: Option<ColliderHandle>,
    ) -> RayBatch<'_> {
        let o = to_vector(origin);
        let (mut lo, mut hi) = (o, o);
        for end in ends {
            let e = to_vector(end);
            lo = lo.min(e);
            hi = hi.max(e);
        }
        // f32 rounding of the segments' points: a generous pad keeps the gather conservative.
        let pad = Vector::splat(BATCH_PAD + 1e-5 * (hi - lo).max_element());
        let reach = Aabb::new(lo - pad, hi + pad);
        let skip = exclude.map(|h| h.into_raw_parts().0);
        let candidates = self
            .bvh
            .intersect_aabb(&reach)
            .filter(|&leaf| Some(leaf) != skip)
            .filter_map(|leaf| {
                let (collider, _) = self.collider_at(leaf)?;
                let aabb = self.bvh.leaf_node(leaf)?.aabb();
                let clipped = Aabb::new(aabb.mins.max(reach.mins), aabb.maxs.min(reach.maxs));
                let cylinder = collider
                    .shape()
                    .as_cylinder()
                    .map(|c| (collider.translation(), c.radius, c.half_height));
                Some(Candidate {
                    collider,
                    cylinder,
                    aabb,
                    clipped,
                })
            })
            .collect();
        RayBatch { origin, candidates }
    }

    /// A fan of rays as [`RayBatch::cast_fan`] describes it, from `origin` (or `origins`),
    /// each ray `max` long, ignoring `exclude`: what [`Scene::cast_ray`] gives for each,
    /// bit for bit, into `out`.
    ///
    /// With `staged`, cast in stages of growing reach (a quarter of `max`, a half, all of
    /// it): each stage gathers the solids near the rays still without a hit, out to its
    /// reach, and casts those rays that far. A hit within the reach is final (every solid
    /// the ray meets before it was gathered); in a crowd most rays of a few scattered
    /// directions (a sonar ring) end on a neighbour in the first stage, whose gathering is
    /// small. (A dense fan, a laser's, pays more for the repeated stages than it saves.)
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn cast_fan(
        &self,
        origin: V3,
        origins: &[V3],
        dirs: &[V3],
        base: f64,
        offsets: &[f64],
        axes: (V3, V3),
        max: f64,
        exclude: Option<ColliderHandle>,
        staged: bool,
        out: &mut Vec<Option<f64>>,
    ) {
        out.clear();
        out.resize(dirs.len(), None);
        if !staged {
            let ends = (0..dirs.len()).map(|k| {
                let start = origins.get(k).copied().unwrap_or(origin);
                add(start, scale(dirs[k], max))
            });
            let batch = self.ray_batch(origin, ends.chain(origins.iter().copied()), exclude);
            batch.cast_fan(origins, dirs, base, offsets, axes, max, out);
            return;
        }
        let start = |k: usize| origins.get(k).copied().unwrap_or(origin);
        let mut pending: Vec<usize> = (0..dirs.len()).collect();
        let (mut sub_origins, mut sub_dirs, mut sub_offsets, mut hits) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for reach in [max / 4.0, max / 2.0, max] {
            let last = reach >= max;
            let reach = if last { max } else { reach };
            sub_dirs.clear();
            sub_dirs.extend(pending.iter().map(|&k| dirs[k]));
            sub_offsets.clear();
            sub_offsets.extend(pending.iter().map(|&k| offsets[k]));
            sub_origins.clear();
            if !origins.is_empty() {
                sub_origins.extend(pending.iter().map(|&k| origins[k]));
            }
            let ends = pending
                .iter()
                .map(|&k| add(start(k), scale(dirs[k], reach)))
                .chain(sub_origins.iter().copied());
            let batch = self.ray_batch(origin, ends, exclude);
            batch.cast_fan(
                &sub_origins,
                &sub_dirs,
                base,
                &sub_offsets,
                axes,
                reach,
                &mut hits,
            );
            let mut still = 0;
            for (i, &hit) in hits.iter().enumerate() {
                let k = pending[i];
                if hit.is_some() || last {
                    out[k] = hit;
                } else {
                    pending[still] = k;
                    still += 1;
                }
            }
            pending.truncate(still);
            if pending.is_empty() || last {
                break;
            }
        }
    }

    /// Whether a body of `shape` at `centre` would overlap anything but `exclude`. When no
    /// other tree box comes near the body's box ([`Scene::alone_in`]), nothing can, and the
    /// shape query is skipped (a spawn in open air: each reset's).
    pub(crate) fn overlaps(
        &self,
        shape: BodyShape,
        centre: V3,
        exclude: Option<ColliderHandle>,
    ) -> bool {
        let half = [shape.radius, shape.radius, shape.half_height];
        let lo: V3 = std::array::from_fn(|i| centre[i] - half[i]);
        let hi: V3 = std::array::from_fn(|i| centre[i] + half[i]);
        if self.alone_in(exclude, lo, hi) {
            return false;
        }
        let cylinder = shape.cylinder();
        self.query(exclude)
            .intersect_shape(upright_pose(centre), &cylinder)
            .next()
            .is_some()
    }

    fn set_clear(&mut self, leaf: u32, value: Room) {
        let i = leaf as usize;
        if i >= self.clear.len() {
            self.clear.resize(i + 1, Room::Unknown);
        }
        self.clear[i] = value;
    }

    /// `leaf` got the new tree box `aabb`: nothing is known any more of the room around it
    /// and around every leaf whose box comes within `SWEEP_PAD` of it.
    fn unclear_near(&mut self, leaf: u32, aabb: &Aabb) {
        self.set_clear(leaf, Room::Unknown);
        let near = Aabb::new(
            aabb.mins - Vector::splat(SWEEP_PAD),
            aabb.maxs + Vector::splat(SWEEP_PAD),
        );
        for other in self.bvh.intersect_aabb(&near) {
            if let Some(room) = self.clear.get_mut(other as usize) {
                *room = Room::Unknown;
            }
        }
    }

    /// Whether `handle`'s motion from `centre` by `motion` stays within its own tree box and
    /// no other box comes within `SWEEP_PAD` of that box (then nothing can be hit). Learns
    /// the second fact with one tree query when it is not known ([`Room`]).
    fn known_clear(
        &mut self,
        handle: ColliderHandle,
        shape: BodyShape,
        centre: V3,
        motion: V3,
    ) -> bool {
        let leaf = handle.into_raw_parts().0;
        let room = self.clear.get(leaf as usize).copied().unwrap_or_default();
        if room == Room::Crowded {
            return false;
        }
        let Some(own) = self.bvh.leaf_node(leaf).map(|n| n.aabb()) else {
            return false;
        };
        let half = [shape.radius, shape.radius, shape.half_height];
        // Rounded outwards by far more than f32's error.
        let lo: V3 = std::array::from_fn(|i| centre[i] + motion[i].min(0.0) - half[i] - 1e-4);
        let hi: V3 = std::array::from_fn(|i| centre[i] + motion[i].max(0.0) + half[i] + 1e-4);
        let inside =
            (0..3).all(|i| f64::from(own.mins[i]) <= lo[i] && hi[i] <= f64::from(own.maxs[i]));
        if !inside {
            return false;
        }
        if room == Room::Clear {
            return true;
        }
        let near = Aabb::new(
            own.mins - Vector::splat(SWEEP_PAD),
            own.maxs + Vector::splat(SWEEP_PAD),
        );
        let alone = self.bvh.intersect_aabb(&near).all(|l| l == leaf);
        self.set_clear(leaf, if alone { Room::Clear } else { Room::Crowded });
        alone
    }

    /// Whether no collider but `exclude` has its tree box inside the box `lo`..`hi` (padded
    /// by `SWEEP_PAD`): then no ray or body within that box can meet anything but `exclude`.
    /// With shortcuts off, `false` (the caller queries).
    pub(crate) fn alone_in(&self, exclude: Option<ColliderHandle>, lo: V3, hi: V3) -> bool {
        if !self.shortcuts {
            return false;
        }
        let pad = f64::from(SWEEP_PAD);
        let lo: V3 = std::array::from_fn(|i| lo[i] - pad);
        let hi: V3 = std::array::from_fn(|i| hi[i] + pad);
        let me = exclude.map(|h| h.into_raw_parts().0);
        self.bvh
            .intersect_aabb(&Aabb::new(to_vector(lo), to_vector(hi)))
            .all(|leaf| Some(leaf) == me)
    }

    /// Whether the scene holds exactly one robot body: its sweeps then read a [`Plan`] and
    /// skip the memos that serve crowds.
    fn lone(&self) -> bool {
        self.shortcuts && self.body_count == 1
    }

    /// Whether the kept [`Plan`] (learnt again when it does not cover the sweep) answers for
    /// the leaf `me` a sweep whose padded swept box is `query`: not unless `me` is the scene's only
    /// robot body (or with shortcuts off: the tree is asked at every sweep).
    fn plan_for(&mut self, me: u32, query: &Aabb) -> bool {
        if !self.lone() {
            return false;
        }
        let known = self.plan.as_ref().is_some_and(|p| p.covers(me, query));
        if !known {
            let region = Aabb::new(
                query.mins - Vector::splat(PLAN_ROOM),
                query.maxs + Vector::splat(PLAN_ROOM),
            );
            let mut near = self.plan.take().map(|p| p.near).unwrap_or_default();
            near.clear();
            let bvh = &self.bvh;
            near.extend(
                bvh.intersect_aabb(&region)
                    .filter(|&l| l != me)
                    .filter_map(|l| {
                        Some(Near {
                            node: *bvh.leaf_node(l)?,
                            solid: self.collider_at(l).and_then(|(c, h)| Solid::of(c, h)),
                        })
                    }),
            );
            self.plan = Some(Plan {
                leaf: me,
                region,
                near,
                mine: self.bvh.leaf_node(me).copied(),
            });
        }
        true
    }

    /// [`Scene::sweep_query`]'s shape cast of the body `handle` at `centre` by `motion`
    /// when every other collider whose tree box comes within the gap `SKIN` (doubled, for
    /// rounding: `SWEEP_PAD`) of the swept box is a box upright to the robot: each cast in
    /// closed form ([`Solid::impact`]), without the query's tree walk and support-map bounds,
    /// the solids read from the robot's [`Plan`] when it is the scene's only one. Nothing
    /// there (most robots, most ticks) is no hit. `None` when one is not such a box (the
    /// caller casts as usual); a collider farther away cannot be hit.
    fn cast_among_boxes(
        &mut self,
        handle: ColliderHandle,
        shape: BodyShape,
        centre: V3,
        motion: V3,
        options: ShapeCastOptions,
    ) -> Option<Option<Impact>> {
        if options.stop_at_penetration {
            return None;
        }
        let me = handle.into_raw_parts().0;
        let query = swept_box(shape, centre, motion);
        let body = upright_pose(centre);
        let cylinder = shape.cylinder();
        let vel = to_vector(motion);
        if self.plan_for(me, &query) {
            let near = self.plan.as_ref().map_or(&[][..], |p| &p.near[..]);
            let solids = meeting(near, &query).map(|n| n.solid);
            return first_impact(solids, &body, vel, &cylinder, options);
        }
        let solids = self.bvh.intersect_aabb(&query).filter(|&l| l != me);
        let solids = solids.map(|leaf| {
            let (collider, handle) = self.collider_at(leaf)?;
            Solid::of(collider, handle)
        });
        first_impact(solids, &body, vel, &cylinder, options)
    }

    /// The contact normal of `leaf`'s last sweep if it is a [`Rest`] that this sweep repeats:
    /// the same start and motion, and no collider but the solid within the reach of any
    /// slide (at most the motion's length in every direction, padded as
    /// [`Scene::cast_among_boxes`] pads).
    fn still_resting(&self, leaf: u32, shape: BodyShape, centre: V3, motion: V3) -> Option<V3> {
        let rest = *self.resting.get(&leaf)?;
        if rest.centre != centre || rest.motion != motion {
            return None;
        }
        let reach = norm(motion) + f64::from(SWEEP_PAD);
        let half = [shape.radius, shape.radius, shape.half_height];
        let lo: V3 = std::array::from_fn(|i| centre[i] - half[i] - reach);
        let hi: V3 = std::array::from_fn(|i| centre[i] + half[i] + reach);
        let near = Aabb::new(to_vector(lo), to_vector(hi));
        let alone = self
            .bvh
            .intersect_aabb(&near)
            .all(|l| l == leaf || l == rest.solid);
        alone.then_some(rest.normal)
    }

    /// Moves the body `handle` from `centre` by `motion`, stopping in front of the first
    /// obstacle and sliding along it (up to three contacts). Returns the new centre.
    /// Also returns the normal of the first surface hit (pointing out of it, towards the
    /// robot), if any.
    pub(crate) fn sweep_contact(
        &mut self,
        handle: ColliderHandle,
        shape: BodyShape,
        centre: V3,
        motion: V3,
    ) -> (V3, Option<V3>) {
        let motion = within_world(centre, motion);
        let leaf = handle.into_raw_parts().0;
        // The scene's only robot reads the solids near it from its plan: the memos of clear
        // rooms and rests would only add their own lookups.
        let memos = self.shortcuts && !self.lone();
        if memos && let Some(normal) = self.still_resting(leaf, shape, centre, motion) {
            return (centre, Some(normal));
        }
        let rest = held_to_max_step(motion);
        if self.lone()
            && let Some(pos) = self.free_move(leaf, shape, centre, rest)
        {
            self.settle(handle, shape, pos, None);
            return (pos, None);
        }
        let cylinder = shape.cylinder();
        let (pos, contact, pressed) = slide(centre, rest, |pos, rest, options| {
            let hit = if memos && self.known_clear(handle, shape, pos, rest) {
                None
            } else if let Some(hit) = self.cast_among_boxes(handle, shape, pos, rest, options) {
                hit
            } else {
                self.sweep_query(Some(handle))
                    .cast_shape(&upright_pose(pos), to_vector(rest), &cylinder, options)
                    .map(|(solid, hit)| Impact::of(solid, &hit))
            }?;
            // (Only the memos ask which solid pressed.)
            let static_now = memos
                && hit.toi == 0.0
                && self
                    .colliders
                    .get(hit.solid)
                    .is_some_and(|c| c.user_data != BODY);
            Some((hit, static_now))
        });
        let memo = match (pressed, contact) {
            (Some(Some(solid)), Some(normal)) if memos && pos == centre => Some(Rest {
                centre,
                motion,
                solid,
                normal,
            }),
            _ => None,
        };
        self.settle(handle, shape, pos, memo);
        (pos, contact)
    }

    /// Starts a [`Glide`] of the scene's only robot body `handle` (`shape`, at `centre`):
    /// sweeps that will stay within `reach` metres of `centre` on every axis. `None` when
    /// the body is not the scene's only one, or a solid within reach is not a box upright
    /// to the robot (its sweeps then go through [`Scene::sweep_contact`]).
    pub(crate) fn glide_begin(
        &mut self,
        handle: ColliderHandle,
        shape: BodyShape,
        centre: V3,
        reach: f64,
    ) -> Option<Glide> {
        if !self.lone() {
            return None;
        }
        let me = handle.into_raw_parts().0;
        let pad = reach + f64::from(SWEEP_PAD);
        let half = [shape.radius, shape.radius, shape.half_height];
        let lo: V3 = std::array::from_fn(|i| centre[i] - half[i] - pad);
        let hi: V3 = std::array::from_fn(|i| centre[i] + half[i] + pad);
        let bound = Aabb::new(to_vector(lo), to_vector(hi));
        if !self.plan_for(me, &bound) {
            return None;
        }
        let plan = self.plan.as_ref()?;
        let mut near = std::mem::take(&mut self.glide_near);
        near.clear();
        near.extend(meeting(&plan.near, &bound).cloned());
        if near.iter().any(|n| n.solid.is_none()) {
            self.glide_near = near;
            return None;
        }
        // Each tick's tree box stays inside the robot's leaf when the box it can reach does
        // (with room for the f32 rounding of each box): then no tick has its box to place.
        let slack: V3 = std::array::from_fn(|i| 1e-6 * (centre[i].abs() + half[i] + reach) + 1e-6);
        let reach_box = Aabb::new(
            to_vector(std::array::from_fn(|i| {
                centre[i] - half[i] - reach - slack[i]
            })),
            to_vector(std::array::from_fn(|i| {
                centre[i] + half[i] + reach + slack[i]
            })),
        );
        let in_leaf = plan.mine.is_some_and(|node| node.contains_aabb(&reach_box));
        // Each sweep's `settle` would forget a rest memo (the only robot makes none).
        if !self.resting.is_empty() {
            self.resting.remove(&me);
        }
        Some(Glide {
            near,
            in_leaf,
            short: reach < 0.5 * MAX_STEP,
        })
    }

    /// [`Scene::sweep_contact`] of a glide's body: the same end, contact and tree box, bit
    /// for bit, cast against the glide's solids. The body's collider stays where the glide
    /// began until [`Scene::glide_end`]: none of the glide's queries reads it (the scene has
    /// no other robot, and a body's own sweeps skip it).
    pub(crate) fn glide_sweep(
        &mut self,
        glide: &Glide,
        handle: ColliderHandle,
        shape: BodyShape,
        centre: V3,
        motion: V3,
    ) -> (V3, Option<V3>) {
        match self.glide_free(glide, handle, shape, centre, motion) {
            Ok(pos) => (pos, None),
            Err(meets) => self.glide_slide(glide, handle, shape, centre, meets),
        }
    }

    /// The rest of [`Scene::glide_sweep`] when its sweep meets a solid of the glide: the
    /// casts against those it meets ([`Meets`], what [`Scene::glide_free`] found).
    pub(crate) fn glide_slide(
        &mut self,
        glide: &Glide,
        handle: ColliderHandle,
        shape: BodyShape,
        centre: V3,
        meets: Meets<'_>,
    ) -> (V3, Option<V3>) {
        let rest = meets.rest;
        let pressed = meets
            .only
            .and_then(|solid| press(solid, shape, centre, rest));
        let (pos, contact) = pressed.unwrap_or_else(|| {
            let cylinder = shape.cylinder();
            let (pos, contact, _) = slide(centre, rest, |pos, rest, options| {
                let query = swept_box(shape, pos, rest);
                let solids = meeting(&glide.near, &query).map(|n| n.solid);
                let body = upright_pose(pos);
                let hit = first_impact(solids, &body, to_vector(rest), &cylinder, options);
                Some((hit.flatten()?, false))
            });
            (pos, contact)
        });
        if !glide.in_leaf {
            self.place_body(handle.into_raw_parts().0, shape, pos);
        }
        (pos, contact)
    }

    /// [`Scene::glide_sweep`] when its sweep meets none of the glide's solids (no contact):
    /// the end, its tree box placed. When it meets one, `Err` with the motion to cast (held
    /// to the world and to [`MAX_STEP`]) and the solid when it is the only one.
    #[inline(always)]
    pub(crate) fn glide_free<'g>(
        &mut self,
        glide: &'g Glide,
        handle: ColliderHandle,
        shape: BodyShape,
        centre: V3,
        motion: V3,
    ) -> Result<V3, Meets<'g>> {
        let motion = within_world(centre, motion);
        // A motion shorter than the glide's reach is never held.
        let rest = if glide.short {
            motion
        } else {
            held_to_max_step(motion)
        };
        if !glide.near.is_empty() {
            let query = swept_box(shape, centre, rest);
            let mut met = meeting(&glide.near, &query);
            if let Some(first) = met.next() {
                let only = met
                    .next()
                    .is_none()
                    .then_some(first.solid.as_ref())
                    .flatten();
                return Err(Meets { rest, only });
            }
        }
        // Nothing within reach of this sweep: the first cast finds nothing, unless the motion
        // is too short to cast.
        let pos = if compare_norm(rest, 1e-9) == Some(std::cmp::Ordering::Less) {
            centre
        } else {
            add(centre, rest)
        };
        if !glide.in_leaf {
            self.place_body(handle.into_raw_parts().0, shape, pos);
        }
        Ok(pos)
    }

    /// Ends a glide: the body's collider where its sweeps left it.
    pub(crate) fn glide_end(&mut self, glide: Glide, handle: ColliderHandle, pos: V3) {
        if let Some(collider) = self.colliders.get_mut(handle) {
            collider.set_position(upright_pose(pos));
        }
        self.glide_near = glide.near;
    }

    /// The sweep's end for the only robot (`me`) moving by `rest` (held to [`MAX_STEP`]) when
    /// its plan has nothing near the swept box: the motion whole, as the casts would find it
    /// (`None`: they are needed, or the plan does not cover the sweep).
    fn free_move(&self, me: u32, shape: BodyShape, centre: V3, rest: V3) -> Option<V3> {
        if compare_norm(rest, 1e-9).is_none_or(|o| o == std::cmp::Ordering::Less) {
            return None;
        }
        let query = swept_box(shape, centre, rest);
        let plan = self.plan.as_ref().filter(|p| p.covers(me, &query))?;
        meeting(&plan.near, &query)
            .next()
            .is_none()
            .then(|| add(centre, rest))
    }

    /// Puts the body `handle` (`shape`) where its sweep left it, at `pos`: its collider, its
    /// tree box in closed form (as `reindex` finds it from the collider), and its rest memo.
    fn settle(&mut self, handle: ColliderHandle, shape: BodyShape, pos: V3, memo: Option<Rest>) {
        let leaf = handle.into_raw_parts().0;
        match memo {
            Some(rest) => {
                self.resting.insert(leaf, rest);
            }
            None if !self.resting.is_empty() => {
                self.resting.remove(&leaf);
            }
            None => {}
        }
        if let Some(collider) = self.colliders.get_mut(handle) {
            collider.set_position(upright_pose(pos));
        }
        self.place_body(leaf, shape, pos);
    }

    /// The tree box of the body `leaf` (`shape`) at `pos`.
    fn place_body(&mut self, leaf: u32, shape: BodyShape, pos: V3) {
        let half = Vector::new(
            shape.radius as f32,
            shape.radius as f32,
            shape.half_height as f32,
        );
        let centre = to_vector(pos);
        let aabb = Aabb::new(centre - half, centre + half);
        // The only robot's tree box, as its plan keeps it: when it holds the new box,
        // `place_leaf` has nothing to do.
        let inside = self.plan.as_ref().is_some_and(|p| {
            p.leaf == leaf && p.mine.is_some_and(|node| node.contains_aabb(&aabb))
        });
        if !inside {
            self.place_leaf(leaf, aabb, true);
        }
    }
}

/// A stretch of ticks in which the scene's only robot body sweeps against a few solids
/// known in advance ([`Scene::glide_begin`]): the plan's solids whose tree boxes meet the
/// box the body can reach in them, in the tree's order. A sweep's query would find exactly
/// those of them that meet its swept box, so its casts are the same.
#[derive(Debug)]
pub(crate) struct Glide {
    near: Vec<Near>,
    /// Every box the body can have in the glide is inside its tree leaf: no tick places it.
    in_leaf: bool,
    /// The reach is under half of [`MAX_STEP`]: no tick's motion is held to it.
    short: bool,
}

/// A glide's sweep that meets solids of the glide ([`Scene::glide_free`]).
#[derive(Debug)]
pub(crate) struct Meets<'g> {
    /// The motion to cast, held to the world and to [`MAX_STEP`].
    rest: V3,
    /// The solid it meets when it meets only one.
    only: Option<&'g Solid>,
}

/// Those of `near` whose tree boxes meet `query`, in their order: what a tree query over
/// `query` finds of them.
fn meeting<'a>(near: &'a [Near], query: &Aabb) -> impl Iterator<Item = &'a Near> {
    let node = BvhNode::leaf(*query, 0);
    near.iter().filter(move |n| n.node.intersects(&node))
}

/// `motion` from `centre`, held to the world's end: ±[`LIMIT`] on every axis
/// (docs/limits.md).
fn within_world(centre: V3, motion: V3) -> V3 {
    std::array::from_fn(|i| (centre[i] + motion[i]).clamp(-LIMIT, LIMIT) - centre[i])
}

/// `motion` held to [`MAX_STEP`] metres.
fn held_to_max_step(motion: V3) -> V3 {
    if compare_norm(motion, MAX_STEP) == Some(std::cmp::Ordering::Greater) {
        scale(motion, MAX_STEP / norm(motion))
    } else {
        motion
    }
}

/// [`slide`] of a glide's body from `centre` by `rest` in the sweep most glides make: the
/// body on a floor (or under a ceiling), `solid`, the only solid its sweep meets,
/// [`Solid::resting`] answering the first cast. A hit there is at time 0 with the normal
/// `(0, 0, ±1)`; the slide that follows keeps the motion's horizontal part and a vertical
/// part of exactly 0 (the motion's `z` less itself), whose swept box is inside the first's:
/// the second cast finds at most the same solid, from the same start, moving along its
/// face: no hit. So the end is the start moved by the slid motion, as [`slide`] finds it,
/// without its second cast. `None` when the sweep is not such a sweep.
fn press(solid: &Solid, shape: BodyShape, centre: V3, rest: V3) -> Option<(V3, Option<V3>)> {
    if compare_norm(rest, 1e-9) == Some(std::cmp::Ordering::Less) {
        return None;
    }
    let body = upright_pose(centre);
    let Some(hit) = solid.resting(&body, to_vector(rest), &shape.cylinder(), CAST)? else {
        return Some((add(centre, rest), None));
    };
    let n = v3(hit.normal);
    let (pos, left, rest) = slide_by(centre, rest, hit.toi, n);
    if rest[2] != 0.0 {
        return None;
    }
    let end = if norm(rest) < MIN_SLIDE * norm(left)
        || compare_norm(rest, 1e-9) == Some(std::cmp::Ordering::Less)
    {
        pos
    } else {
        add(pos, rest)
    };
    Some((end, Some(n)))
}

/// A sweep's cast options: stop [`SKIN`] in front of a solid, out of one already within.
const CAST: ShapeCastOptions = ShapeCastOptions {
    max_time_of_impact: 1.0,
    target_distance: SKIN,
    stop_at_penetration: false,
    compute_impact_geometry_on_penetration: true,
};

/// One move of a [`slide`] from `pos` by `rest`, hitting at `toi` a surface of normal `n`:
/// the position at the hit, the motion left, and the part of it along the surface.
fn slide_by(pos: V3, rest: V3, toi: Real, n: V3) -> (V3, V3, V3) {
    let toi = f64::from(toi).clamp(0.0, 1.0);
    let pos = add(pos, scale(rest, toi));
    let left = scale(rest, 1.0 - toi);
    let into = left[0] * n[0] + left[1] * n[1] + left[2] * n[2];
    let along = if into < 0.0 {
        add(left, scale(n, -into))
    } else {
        left
    };
    (pos, left, along)
}

/// The moves of one sweep from `centre` by `rest`: up to three casts (`cast(pos, rest,
/// options)`: the first hit, and whether it counts as a press on a map solid), each
/// stopping in front of what it hit and sliding along it. Returns the end, the normal of
/// the first surface hit, and the solid every cast hit at once (time 0), if every cast did
/// so and counted it (`Some(None)`: some cast did not).
fn slide(
    centre: V3,
    mut rest: V3,
    mut cast: impl FnMut(V3, V3, ShapeCastOptions) -> Option<(Impact, bool)>,
) -> (V3, Option<V3>, Option<Option<u32>>) {
    let mut contact = None;
    let mut pos = centre;
    let mut pressed: Option<Option<u32>> = None;
    for _ in 0..3 {
        if compare_norm(rest, 1e-9) == Some(std::cmp::Ordering::Less) {
            break;
        }
        let Some((
            Impact {
                solid,
                toi,
                normal: n,
            },
            static_now,
        )) = cast(pos, rest, CAST)
        else {
            pos = add(pos, rest);
            pressed = Some(None);
            break;
        };
        let solid = solid.into_raw_parts().0;
        pressed = match pressed {
            None if static_now => Some(Some(solid)),
            Some(Some(s)) if static_now && s == solid => Some(Some(s)),
            _ => Some(None),
        };
        // Slide: keep the part of the remaining motion that is tangent to the surface.
        let n = v3(n);
        contact.get_or_insert(n);
        let left;
        (pos, left, rest) = slide_by(pos, rest, toi, n);
        if norm(rest) < MIN_SLIDE * norm(left) {
            break;
        }
    }
    (pos, contact, pressed)
}

/// Metres of box kept around a swept body by [`NearBoxes`], beyond its reach.
const NEAR_BOX_MARGIN: f32 = 1.0;

/// parry's dispatcher, except that a shape cast against a box casts against the part of the
/// box near the moving shape: the same faces where the shape can reach them, cut off
/// [`NEAR_BOX_MARGIN`] beyond its reach. parry's GJK ray cast stops within a tolerance
/// relative to the size of the Minkowski difference (f32 ε × 100 × the box's half size), so
/// a body descending onto a 1 km floor stopped up to 14 mm late and sank into the skin and
/// then the floor (issue 21); against the cut box the tolerance is micrometres whatever the
/// box's size.
struct NearBoxes;

impl QueryDispatcher for NearBoxes {
    fn intersection_test(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
    ) -> Result<ShapeIntersection, Unsupported> {
        DefaultQueryDispatcher.intersection_test(pos12, g1, g2)
    }

    fn distance(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
    ) -> Result<ShapeDistance, Unsupported> {
        DefaultQueryDispatcher.distance(pos12, g1, g2)
    }

    fn contact(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        prediction: Real,
    ) -> Result<Option<Contact>, Unsupported> {
        DefaultQueryDispatcher.contact(pos12, g1, g2, prediction)
    }

    fn closest_points(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        max_dist: Real,
    ) -> Result<ClosestPoints, Unsupported> {
        DefaultQueryDispatcher.closest_points(pos12, g1, g2, max_dist)
    }

    fn cast_shapes(
        &self,
        pos12: &Pose,
        local_vel12: Vector,
        g1: &dyn Shape,
        g2: &dyn Shape,
        options: ShapeCastOptions,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        let Some(cuboid) = g1.as_cuboid() else {
            return DefaultQueryDispatcher.cast_shapes(pos12, local_vel12, g1, g2, options);
        };
        if let Some(hit) = box_cast(pos12, local_vel12, g1, g2, options) {
            return Ok(hit);
        }
        // The moving shape's reach in the box's frame, per axis.
        let reach = g2.compute_local_bounding_sphere().radius
            + local_vel12.length() * options.max_time_of_impact
            + options.target_distance
            + NEAR_BOX_MARGIN;
        let c = pos12.translation;
        let h = cuboid.half_extents;
        let lo = (c - Vector::splat(reach)).max(-h);
        let hi = (c + Vector::splat(reach)).min(h);
        if lo.cmpgt(hi).any() {
            return Ok(None); // out of reach
        }
        if lo == -h && hi == h {
            return DefaultQueryDispatcher.cast_shapes(pos12, local_vel12, g1, g2, options);
        }
        let mid = (lo + hi) * 0.5;
        let near = Cuboid::new((hi - lo) * 0.5);
        let shifted = Pose::from_parts(c - mid, pos12.rotation);
        let hit = DefaultQueryDispatcher.cast_shapes(&shifted, local_vel12, &near, g2, options)?;
        Ok(hit.map(|hit| ShapeCastHit {
            witness1: hit.witness1 + mid,
            ..hit
        }))
    }

    fn cast_shapes_nonlinear(
        &self,
        motion1: &NonlinearRigidMotion,
        g1: &dyn Shape,
        motion2: &NonlinearRigidMotion,
        g2: &dyn Shape,
        start_time: Real,
        end_time: Real,
        stop_at_penetration: bool,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        DefaultQueryDispatcher.cast_shapes_nonlinear(
            motion1,
            g1,
            motion2,
            g2,
            start_time,
            end_time,
            stop_at_penetration,
        )
    }
}

/// A shape cast of `g2` (at `pos12` in `g1`'s frame, moving by `vel12`) against `g1` in
/// closed form when `g1` is a box and `g2` a cylinder upright in the box's frame
/// ([`upright_cast`]); `None` when they are not.
fn box_cast(
    pos12: &Pose,
    vel12: Vector,
    g1: &dyn Shape,
    g2: &dyn Shape,
    options: ShapeCastOptions,
) -> Option<Option<ShapeCastHit>> {
    let cuboid = g1.as_cuboid()?;
    let cylinder = g2.as_cylinder()?;
    (is_upright(pos12) && !options.stop_at_penetration)
        .then(|| upright_cast(pos12, vel12, cuboid, cylinder, options))
}

/// The box a body `shape` at `centre` sweeps moving by `motion`, padded by [`SWEEP_PAD`]:
/// every collider a cast of it can hit has a tree box that meets it.
fn swept_box(shape: BodyShape, centre: V3, motion: V3) -> Aabb {
    let half = [shape.radius, shape.radius, shape.half_height];
    let pad = f64::from(SWEEP_PAD);
    let lo: V3 = std::array::from_fn(|i| centre[i] + motion[i].min(0.0) - half[i] - pad);
    let hi: V3 = std::array::from_fn(|i| centre[i] + motion[i].max(0.0) + half[i] + pad);
    Aabb::new(to_vector(lo), to_vector(hi))
}

/// The first hit of the cylinder at `body` moving by `vel` among `solids` (the first of
/// equal times, in their order); `None` when one is not a box upright to the robot.
fn first_impact(
    solids: impl Iterator<Item = Option<Solid>>,
    body: &Pose,
    vel: Vector,
    cylinder: &Cylinder,
    options: ShapeCastOptions,
) -> Option<Option<Impact>> {
    let mut best: Option<Impact> = None;
    for solid in solids {
        if let Some(hit) = solid?.impact(body, vel, cylinder, options)
            && best.as_ref().is_none_or(|b| hit.toi < b.toi)
        {
            best = Some(hit);
        }
    }
    Some(best)
}

/// A swept body's first contact: the solid, the fraction of the motion before it, and the
/// solid's outward normal there (in the world's frame).
struct Impact {
    solid: ColliderHandle,
    toi: Real,
    normal: Vector,
}

impl Impact {
    fn of(solid: ColliderHandle, hit: &ShapeCastHit) -> Self {
        Self {
            solid,
            toi: hit.time_of_impact,
            normal: hit.normal1,
        }
    }
}

fn v3(v: Vector) -> V3 {
    [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
}

/// The closed form's cast ([`crate::upright`]) of `cylinder` at `pos12` in `cuboid`'s
/// frame, moving by `vel12` there.
fn upright_hit(
    pos12: &Pose,
    vel12: Vector,
    cuboid: &Cuboid,
    cylinder: &Cylinder,
    options: ShapeCastOptions,
) -> Option<crate::upright::Hit> {
    let pair = Pair {
        half: v3(cuboid.half_extents),
        radius: f64::from(cylinder.radius),
        half_height: f64::from(cylinder.half_height),
    };
    pair.cast(
        v3(pos12.translation),
        v3(vel12),
        f64::from(options.target_distance),
        f64::from(options.max_time_of_impact),
    )
}

/// Whether a cylinder at `pos12` in a box's frame stands upright in it (parry's cylinders
/// stand along their y axis).
fn is_upright(pos12: &Pose) -> bool {
    (pos12.rotation * Vector::Y).z.abs() >= 1.0 - 1e-6
}

/// [`NearBoxes::cast_shapes`] for an upright cylinder against a box: in closed form
/// ([`crate::upright`]), in the box's frame like parry's.
fn upright_cast(
    pos12: &Pose,
    vel12: Vector,
    cuboid: &Cuboid,
    cylinder: &Cylinder,
    options: ShapeCastOptions,
) -> Option<ShapeCastHit> {
    let hit = upright_hit(pos12, vel12, cuboid, cylinder, options)?;
    let toi = hit.toi as Real;
    let normal1 = Vector::new(
        hit.normal[0] as Real,
        hit.normal[1] as Real,
        hit.normal[2] as Real,
    );
    let witness1 = Vector::new(
        hit.point[0] as Real,
        hit.point[1] as Real,
        hit.point[2] as Real,
    );
    let moved = Pose::from_parts(pos12.translation + vel12 * toi, pos12.rotation);
    Some(ShapeCastHit {
        time_of_impact: toi,
        witness1,
        witness2: moved.inverse_transform_point(witness1 + normal1 * options.target_distance),
        normal1,
        normal2: pos12.rotation.inverse() * -normal1,
        status: if hit.within {
            ShapeCastStatus::PenetratingOrWithinTargetDist
        } else {
            ShapeCastStatus::Converged
        },
        subshape1: 0,
        subshape2: 0,
    })
}

/// Pad (m) of a batch's gathering box.
const BATCH_PAD: f32 = 0.01;

/// The time of impact of `ray` on `collider` within `best` (the leaf test of every cast).
fn leaf_toi(collider: &Collider, ray: &Ray, best: f32) -> Option<f32> {
    match collider.shape().as_cylinder() {
        Some(c) => upright_cylinder_toi(ray, collider.translation(), c.radius, c.half_height, best),
        None => collider
            .shape()
            .cast_ray(collider.position(), ray, best, true),
    }
}

/// A solid gathered for a batch of rays.
struct Candidate<'s> {
    collider: &'s Collider,
    /// Centre, radius and half height of an upright cylinder (intersected in closed form).
    cylinder: Option<(Vector, f32, f32)>,
    /// Its box in the BVH (what a tree walk tests before the solid).
    aabb: Aabb,
    /// That box within the batch's reach (for the angular bound of a fan).
    clipped: Aabb,
}

impl Candidate<'_> {
    /// The leaf test of [`Scene::cast_ray`]: a hit strictly closer than `best`.
    fn toi(&self, ray: &Ray, best: f32) -> Option<f32> {
        let t = match self.cylinder {
            Some((centre, radius, half_height)) => {
                upright_cylinder_toi(ray, centre, radius, half_height, best)
            }
            None => {
                // The tree's box test first (parry's shape casts cost far more); a NaN of a
                // ray grazing a face keeps the solid in.
                if !slab_may_hit(&self.aabb, ray, best) {
                    return None;
                }
                self.collider
                    .shape()
                    .cast_ray(self.collider.position(), ray, best, true)
            }
        };
        t.filter(|&t| t < best)
    }
}

/// Whether `ray` may meet `aabb` before `best` (conservative: true when unsure).
fn slab_may_hit(aabb: &Aabb, ray: &Ray, best: f32) -> bool {
    let (mut tmin, mut tmax) = (f32::NEG_INFINITY, f32::INFINITY);
    for i in 0..3 {
        let inv = 1.0 / ray.dir[i];
        let t1 = (aabb.mins[i] - ray.origin[i]) * inv;
        let t2 = (aabb.maxs[i] - ray.origin[i]) * inv;
        if t1.is_nan() || t2.is_nan() {
            continue;
        }
        tmin = tmin.max(t1.min(t2));
        tmax = tmax.min(t1.max(t2));
    }
    // A little slack: the tree's own (SIMD) test must never be the stricter one.
    let slack = 1e-4 * (1.0 + tmax.abs().min(1e6));
    tmax + slack >= tmin && tmax + slack >= 0.0 && tmin - slack < best
}

/// The solids near one origin, gathered once for many rays ([`Scene::ray_batch`]).
pub(crate) struct RayBatch<'s> {
    origin: V3,
    candidates: Vec<Candidate<'s>>,
}

impl RayBatch<'_> {
    /// Exactly [`Scene::cast_ray`] from the batch's origin (for a ray within its reach).
    pub(crate) fn cast(&self, dir: V3, max: f64) -> Option<f64> {
        let ray = Ray::new(to_vector(self.origin), to_vector(dir));
        let mut best = max as f32;
        let mut hit = None;
        for c in &self.candidates {
            if let Some(t) = c.toi(&ray, best) {
                best = t;
                hit = Some(t);
            }
        }
        hit.map(f64::from)
    }

    /// A fan of rays: `dirs[k]` has azimuth `base + offsets[k]` about the axis of the
    /// orthonormal pair (`e1`, `e2`) (its angle from `e1` towards `e2`), `offsets` sorted
    /// from largest to smallest and spanning at most a turn. Writes what
    /// [`Scene::cast_ray`] gives for each ray into `out`; each solid is tried only on the
    /// rays whose azimuth falls within the angle it covers as seen from the origin.
    ///
    /// The rays start at the batch's origin, or, if `origins` is not empty, ray `k` at
    /// `origins[k]` (a sonar ring: each on the rim, pointing away from the centre). The
    /// bounds then allow for how far each ray's line passes from the batch's origin.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn cast_fan(
        &self,
        origins: &[V3],
        dirs: &[V3],
        base: f64,
        offsets: &[f64],
        (e1, e2): (V3, V3),
        max: f64,
        out: &mut Vec<Option<f64>>,
    ) {
        debug_assert_eq!(dirs.len(), offsets.len());
        debug_assert!(origins.is_empty() || origins.len() == dirs.len());
        let dot = |a: V3, b: V3| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let origin_of = |k: usize| origins.get(k).copied().unwrap_or(self.origin);
        let rays: Vec<Ray> = (0..dirs.len())
            .map(|k| Ray::new(to_vector(origin_of(k)), to_vector(dirs[k])))
            .collect();
        // Ray k runs along the line through the batch's origin in its direction, from
        // `ahead` on, at most `aside` away from it: the bounds below are taken on that line,
        // the spheres widened by the largest `aside`, the distances cut by `shift[k]`, both.
        let (mut shift, mut widen) = (Vec::new(), 0.0f64);
        for (&start, &dir) in origins.iter().zip(dirs) {
            let d = sub(start, self.origin);
            let ahead = dot(d, dir).max(0.0);
            let aside = norm(sub(d, scale(dir, ahead))) * (1.0 + 1e-9) + 1e-9;
            widen = widen.max(aside);
            shift.push(((ahead + aside) * (1.0 + 1e-6)) as f32);
        }
        let mut best = vec![max as f32; dirs.len()];
        let mut hit = vec![false; dirs.len()];
        let mut test = |c: &Candidate<'_>, near: f32, k: usize| {
            // No hit can be nearer than the sphere: beams that already hit something
            // nearer skip the solid. (The 1 mm of slack in `near` covers the rounding.)
            if near - shift.get(k).copied().unwrap_or(0.0) >= best[k] {
                return;
            }
            if let Some(t) = c.toi(&rays[k], best[k]) {
                best[k] = t;
                hit[k] = true;
            }
        };
        // Each solid's bounding sphere (around its part within reach), nearest first.
        let mut spheres: Vec<(f32, V3, f64, &Candidate<'_>)> = self
            .candidates
            .iter()
            .map(|c| {
                // An upright cylinder's own sphere is tighter than its box's.
                let (centre, radius) = match c.cylinder {
                    Some((centre, r, h)) => (centre, r.hypot(h)),
                    None => (c.clipped.center(), c.clipped.half_extents().length()),
                };
                let radius = f64::from(radius) + f64::from(BATCH_PAD) + widen;
                let u = [
                    f64::from(centre.x) - self.origin[0],
                    f64::from(centre.y) - self.origin[1],
                    f64::from(centre.z) - self.origin[2],
                ];
                let near = ((norm(u) - radius) * (1.0 - 1e-6) - 1e-3).max(0.0) as f32;
                (near, u, radius, c)
            })
            .collect();
        spheres.sort_by(|a, b| a.0.total_cmp(&b.0));
        for &(near, u, radius, c) in &spheres {
            let (u1, u2) = (dot(u, e1), dot(u, e2));
            let across = u1.hypot(u2);
            // (NaN counts as through.)
            if across.is_nan() || across <= radius * 1.001 + 1e-6 {
                // The axis passes through it: any azimuth may hit.
                for k in 0..dirs.len() {
                    test(c, near, k);
                }
                continue;
            }
            let half = (radius / across).asin() + 1e-6 + 1e-12 * base.abs();
            // Within (−π, π]; the offsets are too.
            let mut centre_offset = (u2.atan2(u1) - base).rem_euclid(std::f64::consts::TAU);
            if centre_offset > std::f64::consts::PI {
                centre_offset -= std::f64::consts::TAU;
            }
            // The covered range of offsets, and its copies a turn either side where they
            // can reach the offsets (within ±π).
            let wraps_low = centre_offset - half < -std::f64::consts::PI + 1e-3;
            let wraps_high = centre_offset + half > std::f64::consts::PI - 1e-3;
            for turn in [-1.0, 0.0, 1.0] {
                if (turn < 0.0 && !wraps_high) || (turn > 0.0 && !wraps_low) {
                    continue;
                }
                let mid = centre_offset + turn * std::f64::consts::TAU;
                let (lo, hi) = (mid - half, mid + half);
                let first = offsets.partition_point(|&o| o > hi);
                let end = offsets.partition_point(|&o| o >= lo);
                for k in first..end.max(first) {
                    test(c, near, k);
                }
            }
        }
        out.clear();
        out.extend(
            best.iter()
                .zip(&hit)
                .map(|(&t, &h)| h.then_some(f64::from(t))),
        );
    }
}

/// Time of impact of `ray` (unit direction) on a solid upright cylinder (axis along z)
/// centred at `centre`, if within `max`; 0 when the ray starts inside.
pub(crate) fn upright_cylinder_toi(
    ray: &Ray,
    centre: Vector,
    radius: f32,
    half_height: f32,
    max: f32,
) -> Option<f32> {
    let p = ray.origin - centre;
    let d = ray.dir;
    let r2 = radius * radius;
    let inside_disc = |x: f32, y: f32| x * x + y * y <= r2;
    if inside_disc(p.x, p.y) && p.z.abs() <= half_height {
        return Some(0.0);
    }
    let mut best: Option<f32> = None;
    let mut take = |t: f32| {
        if t >= 0.0 && t <= max && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    };
    // The side: |p.xy + t·d.xy| = r, entering (the smaller root).
    let a = d.x * d.x + d.y * d.y;
    if a > f32::EPSILON {
        let b = p.x * d.x + p.y * d.y;
        let c = p.x * p.x + p.y * p.y - r2;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let t = (-b - disc.sqrt()) / a;
            if (p.z + t * d.z).abs() <= half_height {
                take(t);
            }
        }
    }
    // The caps: z = ±h within the disc.
    if d.z.abs() > f32::EPSILON {
        for cap in [-half_height, half_height] {
            let t = (cap - p.z) / d.z;
            if inside_disc(p.x + t * d.x, p.y + t * d.y) {
                take(t);
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use rapier3d::prelude::ColliderBuilder;

    #[test]
    fn the_upright_rotation_is_the_quarter_turn_about_x_bit_for_bit() {
        let turn = Rotation::from_rotation_x(std::f32::consts::FRAC_PI_2);
        let bits = |q: Rotation| [q.x, q.y, q.z, q.w].map(f32::to_bits);
        assert_eq!(bits(UPRIGHT), bits(turn));
    }

    #[test]
    fn ray_hits_box_and_ignores_excluded() {
        let mut scene = Scene::new();
        scene.insert(
            ColliderBuilder::cuboid(0.5, 5.0, 5.0).position(Pose::translation(5.5, 0.0, 0.0)),
        );
        let me = scene.insert_body(
            BodyShape {
                radius: 0.3,
                half_height: 0.1,
            },
            [0.0, 0.0, 0.0],
        );
        let d = scene.cast_ray([0.0; 3], [1.0, 0.0, 0.0], 10.0, Some(me));
        assert!((d.unwrap() - 5.0).abs() < 1e-4);
        // Without the exclusion the ray starts inside the body (solid: hit at 0).
        assert_eq!(
            scene.cast_ray([0.0; 3], [1.0, 0.0, 0.0], 10.0, None),
            Some(0.0)
        );
        assert!(
            scene
                .cast_ray([0.0; 3], [-1.0, 0.0, 0.0], 10.0, Some(me))
                .is_none()
        );
    }

    /// A crowd flying on one command (a swarm, the benchmark's grid) must not leave its tree
    /// boxes all on one tick: each box regrown is a tree update, and 10,000 on one tick made
    /// the longest tick twice the median (issue 27's tail). Before the spread margins every
    /// robot left its box on the first tick it moved and then every 50 ticks, all together;
    /// with a margin by leaf, all together again when they came back to where they started.
    #[test]
    fn a_crowd_moving_together_regrows_its_tree_boxes_on_different_ticks() {
        let shape = BodyShape {
            radius: 0.45,
            half_height: 0.1,
        };
        let mut scene = Scene::new();
        let mut bodies: Vec<(ColliderHandle, V3)> = (0..400)
            .map(|i| {
                let centre = [f64::from(i % 20) * 1.5, f64::from(i / 20) * 1.5, -2.0];
                (scene.insert_body(shape, centre), centre)
            })
            .collect();
        scene.refresh();
        let boxes = |scene: &Scene, bodies: &[(ColliderHandle, V3)]| -> Vec<Aabb> {
            bodies
                .iter()
                .map(|(h, _)| scene.bvh.leaf_node(h.into_raw_parts().0).unwrap().aabb())
                .collect()
        };
        let mut most = 0;
        // 0.2 m/s at 200 Hz, out for 1 s and back, twice (the benchmark's flight): each leg
        // four times through the least margin.
        for tick in 0..800 {
            let before = boxes(&scene, &bodies);
            let dx = if (tick / 200) % 2 == 0 { 0.001 } else { -0.001 };
            for (handle, centre) in &mut bodies {
                *centre = scene
                    .sweep_contact(*handle, shape, *centre, [dx, 0.0, 0.0])
                    .0;
            }
            let after = boxes(&scene, &bodies);
            let regrown = before.iter().zip(&after).filter(|(a, b)| a != b).count();
            most = most.max(regrown);
        }
        assert!(
            most <= bodies.len() / 10,
            "{most} of {} robots regrew their tree boxes on one tick",
            bodies.len()
        );
    }

    /// The shortcut for a body resting on (or under) a level box answers as the full
    /// closed-form cast, bit for bit: bodies over, under and beside random boxes, from
    /// overlapping to beyond the target distance, on the rim and at ±0, moving every way
    /// (zeros of either sign included).
    #[test]
    fn a_resting_body_casts_as_the_full_cast() {
        let mut seed = 0x2545_F491_4F6C_DD1D_u64;
        let mut unit =
            move || (crate::noise::splitmix(&mut seed) >> 40) as f32 / (1u64 << 24) as f32;
        let cylinder = BodyShape {
            radius: 0.45,
            half_height: 0.1,
        }
        .cylinder();
        let options = ShapeCastOptions {
            max_time_of_impact: 1.0,
            target_distance: SKIN,
            stop_at_penetration: false,
            compute_impact_geometry_on_penetration: true,
        };
        let (mut shortcuts, mut hits) = (0, 0);
        for case in 0..20_000 {
            let half = Vector::new(0.1 + 3.0 * unit(), 0.1 + 3.0 * unit(), 0.05 + unit());
            let centre = Vector::new(6.0 * unit() - 3.0, 6.0 * unit() - 3.0, 4.0 * unit() - 2.0);
            let solid = Solid {
                handle: ColliderHandle::from_raw_parts(3, 0),
                pose: Pose::from_translation(centre),
                cuboid: Cuboid::new(half),
                level: true,
            };
            // Across the face, on its rim, beyond it, or at ±0.
            let mut across = |h: f32| match (4.0 * unit()) as u8 {
                0 => h,
                1 => -h,
                2 => [0.0, -0.0][(2.0 * unit()) as usize],
                _ => (2.0 * unit() - 1.0) * 1.2 * h,
            };
            let (x, y) = (across(half.x), across(half.y));
            // A gap to the face of 0 to 0.03 m (the target 0.01 exactly now and then), or
            // overlapping.
            let gap = match (8.0 * unit()) as u8 {
                0 => SKIN,
                1 => -0.05,
                _ => 0.03 * unit(),
            };
            let z = (half.z + 0.1 + gap) * if unit() < 0.5 { 1.0 } else { -1.0 };
            let body = upright_pose(v3(centre + Vector::new(x, y, z)));
            let mut speed = || match (5.0 * unit()) as u8 {
                0 => 0.0,
                1 => -0.0,
                _ => 6.0 * unit() - 3.0,
            };
            let vel = Vector::new(speed(), speed(), speed());
            let Some(fast) = solid.resting(&body, vel, &cylinder, options) else {
                continue;
            };
            shortcuts += 1;
            let full = solid.full_impact(&body, vel, &cylinder, options);
            let bits = |i: &Option<Impact>| {
                i.as_ref().map(|i| {
                    (
                        i.solid,
                        i.toi.to_bits(),
                        i.normal.to_array().map(f32::to_bits),
                    )
                })
            };
            hits += usize::from(fast.is_some());
            assert_eq!(
                bits(&fast),
                bits(&full),
                "case {case}: {body:?} {vel:?} {solid:?}"
            );
        }
        assert!(
            shortcuts > 3000 && hits > 1000,
            "{shortcuts} shortcuts, {hits} hits"
        );
    }

    #[test]
    fn closed_form_cylinder_rays_agree_with_parry() {
        let shape = BodyShape {
            radius: 0.45,
            half_height: 0.1,
        };
        let centre = [1.0, -0.5, -1.0];
        let mut scene = Scene::new();
        let handle = scene.insert_body(shape, centre);
        let collider = scene.colliders.get(handle).unwrap();
        let mut checked = 0;
        // Rays from a ring of origins in many directions, some grazing, some from above.
        for i in 0..24 {
            let a = f64::from(i) * 0.2618;
            let origin = [
                centre[0] + 2.0 * a.cos(),
                centre[1] + 2.0 * a.sin(),
                -1.05 + 0.01 * f64::from(i % 5),
            ];
            for j in 0..36 {
                let yaw = f64::from(j) * 0.1745;
                for pitch in [-1.2, -0.3, 0.0, 0.05, 0.6] {
                    let dir = direction(pitch, yaw);
                    let ray = Ray::new(to_vector(origin), to_vector(dir));
                    let ours = scene.cast_ray(origin, dir, 10.0, None);
                    let parry = collider
                        .shape()
                        .cast_ray(collider.position(), &ray, 10.0, true)
                        .map(f64::from);
                    match (ours, parry) {
                        (Some(x), Some(y)) => assert!((x - y).abs() < 1e-3, "{x} vs {y}"),
                        (None, None) => {}
                        (x, y) => panic!("ray {origin:?} {dir:?}: ours {x:?}, parry {y:?}"),
                    }
                    checked += usize::from(ours.is_some());
                }
            }
        }
        assert!(checked > 50, "only {checked} hits checked");
    }

    /// Random solids for [`random_scene`]: `count` of them, each of a kind below `kinds`
    /// (0 box, 1 cylinder, 2 robot body, 3 mesh), centre, size and yaw.
    fn random_solids(
        kinds: u8,
        count: std::ops::Range<usize>,
    ) -> impl proptest::strategy::Strategy<Value = Vec<(u8, [f32; 3], [f32; 3], f32)>> {
        proptest::collection::vec(
            (
                0u8..kinds,
                proptest::array::uniform3(-4.0f32..4.0),
                proptest::array::uniform3(0.0f32..1.5),
                -3.2f32..3.2,
            ),
            count,
        )
    }

    /// A random scene: yawed boxes, upright cylinders (solids and robot bodies), a small
    /// triangle mesh, all within a few metres of the origin.
    fn random_scene(solids: &[(u8, [f32; 3], [f32; 3], f32)]) -> Scene {
        let mut scene = Scene::new();
        for &(kind, c, s, yaw) in solids {
            let s = s.map(|v| 0.05 + v.abs());
            let pose = Pose::new(Vector::new(c[0], c[1], c[2]), Vector::new(0.0, 0.0, yaw));
            match kind % 4 {
                0 => {
                    scene.insert(ColliderBuilder::cuboid(s[0], s[1], s[2]).position(pose));
                }
                1 => {
                    scene.insert(
                        ColliderBuilder::cylinder(s[2], s[0])
                            .position(upright_pose(c.map(f64::from))),
                    );
                }
                2 => {
                    let body = BodyShape {
                        radius: f64::from(s[0]),
                        half_height: f64::from(s[2]),
                    };
                    let handle = scene.insert_body(body, c.map(f64::from));
                    // Moved a little: its tree box then carries the margin.
                    let motion = [f64::from(s[1]) * 0.01, 0.0, 0.0];
                    scene.sweep_contact(handle, body, c.map(f64::from), motion);
                }
                _ => {
                    let v = |x: f32, y: f32, z: f32| Vector::new(c[0] + x, c[1] + y, c[2] + z);
                    let vertices = vec![
                        v(0.0, 0.0, 0.0),
                        v(s[0], 0.0, 0.0),
                        v(0.0, s[1], 0.0),
                        v(0.0, 0.0, -s[2]),
                    ];
                    let triangles = vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
                    scene.insert(ColliderBuilder::trimesh(vertices, triangles).expect("mesh"));
                }
            }
        }
        scene
    }

    proptest::proptest! {
        /// A laser fan cast in one batch gives, beam for beam and bit for bit, what one
        /// tree walk per beam gives; so do the batch's single casts (sonar cones), and fans
        /// whose rays start on a ring around the origin (the horizontal sonars, whose mounts
        /// are rounded: a little off the radial line).
        #[test]
        fn batched_fans_equal_per_beam_casts(
            solids in random_solids(4, 0..24),
            origin in proptest::array::uniform3(-3.0f64..3.0),
            yaw in -20.0f64..20.0,
            pitch in prop_oneof_pitch(),
            max in 0.5f64..8.0,
            beams in 1usize..240,
            fov in 0.1f64..std::f64::consts::TAU,
            (roll, tilt) in (-0.6f64..0.6, -0.6f64..0.6),
            tilted in proptest::bool::ANY,
            ring in proptest::option::of((0.0f64..0.8, -0.01f64..0.01)),
        ) {
            let mut scene = random_scene(&solids);
            // The scanning robot's own body, excluded as the sensors exclude it.
            let me = BodyShape { radius: 0.45, half_height: 0.1 };
            let me = (!scene.overlaps(me, origin, None)).then(|| scene.insert_body(me, origin));
            let offsets: Vec<f64> = (0..beams)
                .map(|k| fov / 2.0 - fov * k as f64 / beams as f64)
                .collect();
            // A body tilted by roll about x, then pitch about y (a quadrotor's sensors): the
            // directions and the azimuth axes turn together.
            let turn = |v: V3| -> V3 {
                if !tilted {
                    return v;
                }
                let (sr, cr) = roll.sin_cos();
                let (sp, cp) = tilt.sin_cos();
                let v = [v[0], cr * v[1] - sr * v[2], sr * v[1] + cr * v[2]];
                [cp * v[0] + sp * v[2], v[1], -sp * v[0] + cp * v[2]]
            };
            let dirs: Vec<V3> =
                offsets.iter().map(|o| turn(direction(pitch, yaw + o))).collect();
            // On the ring: `radius` out along the ray, then `off` aside (along z, turned).
            let origins: Vec<V3> = match ring {
                None => Vec::new(),
                Some((radius, off)) => dirs
                    .iter()
                    .map(|&d| add(add(origin, scale(d, radius)), turn([0.0, 0.0, off])))
                    .collect(),
            };
            let start = |k: usize| origins.get(k).copied().unwrap_or(origin);
            let ends = (0..dirs.len())
                .map(|k| add(start(k), scale(dirs[k], max)))
                .chain(origins.iter().copied());
            let batch = scene.ray_batch(origin, ends, me);
            let mut fan = Vec::new();
            let axes = (turn([1.0, 0.0, 0.0]), turn([0.0, 1.0, 0.0]));
            batch.cast_fan(&origins, &dirs, yaw, &offsets, axes, max, &mut fan);
            // In stages of growing reach, as the sensors cast their fans.
            let mut staged = Vec::new();
            scene.cast_fan(origin, &origins, &dirs, yaw, &offsets, axes, max, me, true, &mut staged);
            let mut whole = Vec::new();
            scene.cast_fan(origin, &origins, &dirs, yaw, &offsets, axes, max, me, false, &mut whole);
            proptest::prop_assert_eq!(&whole, &fan);
            for (k, &dir) in dirs.iter().enumerate() {
                let walk = scene.cast_ray(start(k), dir, max, me);
                proptest::prop_assert_eq!(staged[k].map(f64::to_bits), walk.map(f64::to_bits),
                    "staged ray {} from {:?} dir {:?}", k, start(k), dir);
                if !origins.is_empty() {
                    proptest::prop_assert_eq!(fan[k].map(f64::to_bits), walk.map(f64::to_bits),
                        "ring ray {} from {:?} dir {:?}", k, start(k), dir);
                    continue;
                }
                proptest::prop_assert_eq!(fan[k].map(f64::to_bits), walk.map(f64::to_bits),
                    "beam {} dir {:?}: fan {:?} walk {:?}", k, dir, fan[k], walk);
                proptest::prop_assert_eq!(batch.cast(dir, max), walk);
            }
        }
    }

    proptest::proptest! {
        /// `compare_norm` answers as comparing the square root, near the limit (where it
        /// takes the root) and far from it, for the limits the sweep asks about.
        #[test]
        fn comparing_a_norm_answers_as_the_square_root(
            direction in proptest::array::uniform3(-1.0f64..1.0),
            scale in -3.0f64..3.0,
            limit in proptest::sample::select(vec![1e-9, MAX_STEP, 0.5]),
        ) {
            let k = limit * 10f64.powf(scale) / norm(direction).max(1e-300);
            let a = direction.map(|v| v * k);
            proptest::prop_assert_eq!(compare_norm(a, limit), norm(a).partial_cmp(&limit));
            proptest::prop_assert_eq!(compare_norm(a, norm(a)), Some(std::cmp::Ordering::Equal));
        }
    }

    proptest::proptest! {
        /// Whether a body overlaps anything is the shape query's answer, with the tree-box
        /// test in front of it or not: bodies placed at random among random solids, some
        /// touching them, some inside.
        #[test]
        fn the_open_air_test_answers_as_the_shape_query(
            solids in random_solids(2, 1..8),
            places in proptest::collection::vec(
                (-4.5f64..4.5, -4.5f64..4.5, -1.0f64..1.0), 1..40),
        ) {
            let shape = BodyShape { radius: 0.45, half_height: 0.1 };
            let fast = random_scene(&solids);
            let mut slow = random_scene(&solids);
            slow.shortcuts = false;
            for &(x, y, z) in &places {
                proptest::prop_assert_eq!(
                    fast.overlaps(shape, [x, y, z], None),
                    slow.overlaps(shape, [x, y, z], None),
                    "at {:?}", (x, y, z)
                );
            }
        }
    }

    proptest::proptest! {
        /// Robots swept around random solids and each other end where shape-casting every
        /// move puts them, bit for bit (the skipped sweeps skip only casts that hit nothing).
        #[test]
        fn skipped_sweeps_equal_shape_casts(
            solids in random_solids(2, 0..8),
            robots in proptest::collection::vec(
                ((-2.5f64..2.5, -2.5f64..2.5, -0.05f64..0.05),
                 proptest::array::uniform3(-0.03f64..0.03)),
                1..24,
            ),
            ticks in 1usize..120,
        ) {
            let shape = BodyShape { radius: 0.45, half_height: 0.1 };
            let mut fast = random_scene(&solids);
            let mut slow = random_scene(&solids);
            slow.shortcuts = false;
            let mut bodies = Vec::new();
            for &((x, y, z), motion) in &robots {
                let centre = [x, y, z];
                if fast.overlaps(shape, centre, None) {
                    continue;
                }
                let a = fast.insert_body(shape, centre);
                let b = slow.insert_body(shape, centre);
                bodies.push((a, b, centre, centre, motion));
            }
            for tick in 0..ticks {
                fast.refresh();
                slow.refresh();
                for (a, b, pa, pb, motion) in &mut bodies {
                    // Now and then a robot hovers, turns back or speeds up.
                    let k = [1.0, 0.0, -1.0, 0.2, 4.0][(tick / 9) % 5];
                    let m = motion.map(|v| v * k);
                    if m == [0.0; 3] {
                        continue;
                    }
                    *pa = fast.sweep_contact(*a, shape, *pa, m).0;
                    *pb = slow.sweep_contact(*b, shape, *pb, m).0;
                    proptest::prop_assert_eq!(pa.map(f64::to_bits), pb.map(f64::to_bits));
                }
            }
        }
    }

    proptest::proptest! {
        /// The scene's only robot, whose sweeps read the solids near it from its plan, ends
        /// where the tree's answers put it, bit for bit, with the same contact normals and
        /// tree box: long flights between a floor, a ceiling and random solids, across many
        /// plans, with refits between the sweeps.
        #[test]
        fn a_lone_robot_sweeps_from_its_plan_as_from_the_tree(
            solids in random_solids(2, 0..10),
            start in (-2.5f64..2.5, -2.5f64..2.5, -0.6f64..0.6),
            motions in proptest::collection::vec(proptest::array::uniform3(-0.06f64..0.06), 1..12),
            ticks in 1usize..400,
        ) {
            let shape = BodyShape { radius: 0.45, half_height: 0.1 };
            let mut fast = random_scene(&solids);
            let mut slow = random_scene(&solids);
            slow.shortcuts = false;
            for scene in [&mut fast, &mut slow] {
                for z in [-1.0f32, 1.0] {
                    scene.insert(ColliderBuilder::cuboid(6.0, 6.0, 0.2).translation(Vector::new(0.0, 0.0, z * 0.95)));
                }
            }
            let centre = [start.0, start.1, start.2];
            proptest::prop_assume!(!fast.overlaps(shape, centre, None));
            let a = fast.insert_body(shape, centre);
            let b = slow.insert_body(shape, centre);
            let (mut pa, mut pb) = (centre, centre);
            for tick in 0..ticks {
                fast.refresh();
                slow.refresh();
                if tick % 7 == 6 {
                    fast.refit();
                }
                let m = motions[(tick / 13) % motions.len()];
                let (na, ca) = fast.sweep_contact(a, shape, pa, m);
                let (nb, cb) = slow.sweep_contact(b, shape, pb, m);
                (pa, pb) = (na, nb);
                proptest::prop_assert_eq!(pa.map(f64::to_bits), pb.map(f64::to_bits), "tick {}", tick);
                proptest::prop_assert_eq!(ca.map(|n| n.map(f64::to_bits)), cb.map(|n| n.map(f64::to_bits)));
                // Its tree box too (what rays and other bodies' queries read).
                let leaf = |scene: &Scene, h: ColliderHandle| {
                    scene.bvh.leaf_node(h.into_raw_parts().0).map(|n| (n.mins().to_array(), n.maxs().to_array()))
                };
                proptest::prop_assert_eq!(leaf(&fast, a), leaf(&slow, b), "tick {}", tick);
            }
        }
    }

    /// Level scans mostly, tilted ones and straight up or down now and then.
    fn prop_oneof_pitch() -> impl proptest::strategy::Strategy<Value = f64> {
        use proptest::prelude::*;
        prop_oneof![
            3 => Just(0.0),
            3 => -1.6f64..1.6,
            1 => Just(std::f64::consts::FRAC_PI_2),
            1 => Just(-std::f64::consts::FRAC_PI_2),
        ]
    }

    #[test]
    fn a_first_body_moves_into_the_leaf_the_map_kept_without_a_refit() {
        let map = crate::Map::embedded("empty_room").expect("an embedded map");
        let template = map.scene();
        let mut scene = Scene::copy_of(&template);
        // The kept leaf is where nothing looks: a ray down the room's whole height (and far
        // past the floor) finds the floor's top at z = 0.
        let down = scene.cast_ray([0.0, 0.0, -4.0], [0.0, 0.0, 1.0], 1e5, None);
        assert!(down.is_some_and(|d| (d - 4.0).abs() < 1e-4), "{down:?}");
        let shape = BodyShape {
            radius: 0.45,
            half_height: 0.1,
        };
        let body = scene.insert_body(shape, [0.0, 0.0, -1.5]);
        assert_eq!(body.into_raw_parts().0 as usize, template.colliders.len());
        assert!(
            !scene.stale,
            "the body was inserted as a new leaf: the next tick refits"
        );
        // The tree finds the body where it is: the same ray stops on its top at z = -1.6.
        let hit = scene.cast_ray([0.0, 0.0, -4.0], [0.0, 0.0, 1.0], 1e5, None);
        assert!(hit.is_some_and(|d| (d - 2.4).abs() < 1e-4), "{hit:?}");
    }

    #[test]
    fn moved_robots_stay_visible_to_rays() {
        // A crowd that moves after the tree was built (parry's incremental leaf updates
        // once left inner boxes that missed moved robots: scans looked through them).
        let shape = BodyShape {
            radius: 0.45,
            half_height: 0.1,
        };
        let mut scene = Scene::new();
        let mut bodies = Vec::new();
        for i in 0..300 {
            let centre = [
                f64::from(i % 15) * 1.5,
                f64::from((i / 15) % 10) * 1.5,
                -2.0 - f64::from(i / 150),
            ];
            bodies.push((scene.insert_body(shape, centre), centre));
        }
        scene.refresh();
        for _ in 0..30 {
            for (step, (handle, centre)) in bodies.iter_mut().enumerate() {
                let a = step as f64 * 0.7;
                let motion = [0.01 * a.cos(), 0.01 * a.sin(), 0.001 * (a * 3.0).sin()];
                *centre = scene.sweep_contact(*handle, shape, *centre, motion).0;
            }
        }
        scene.refresh();
        let mut hits = 0;
        for (i, &(_, centre)) in bodies.iter().enumerate().step_by(7) {
            for k in 0..90 {
                let dir = direction(0.0, f64::from(k) * 0.0698 + i as f64);
                let origin = [centre[0], centre[1], centre[2] + 0.05];
                let me = Some(bodies[i].0);
                let walk = scene.cast_ray(origin, dir, 6.0, me);
                let mut truth = None;
                for &(other, _) in &bodies {
                    if Some(other) != me {
                        let c = scene.colliders.get(other).expect("body");
                        let ray = Ray::new(to_vector(origin), to_vector(dir));
                        if let Some(t) = leaf_toi(c, &ray, 6.0) {
                            truth = Some(truth.map_or(t, |b: f32| b.min(t)));
                        }
                    }
                }
                assert_eq!(walk, truth.map(f64::from), "robot {i} beam {k}");
                hits += usize::from(walk.is_some());
            }
        }
        assert!(hits > 500, "only {hits} hits");
    }

    #[test]
    fn walls_are_counted_as_the_robot_monitor_counts_them() {
        let mut scene = Scene::new();
        let wall = |x: f32, thick: f32| {
            ColliderBuilder::cuboid(thick / 2.0, 5.0, 5.0).position(Pose::translation(x, 0.0, 0.0))
        };
        scene.insert(wall(2.0, 0.1));
        scene.insert(wall(4.0, 1.5)); // thick: once
        scene.insert_body(
            BodyShape {
                radius: 0.3,
                half_height: 0.2,
            },
            [6.0, 0.0, 0.0],
        ); // a robot: never
        scene.refit();
        assert_eq!(scene.obstacles_between([0.0; 3], [8.0, 0.0, 0.0]), 2);
        assert_eq!(scene.obstacles_between([8.0, 0.0, 0.0], [0.0; 3]), 2);
        assert_eq!(scene.obstacles_between([0.0; 3], [1.0, 0.0, 0.0]), 0);
        assert_eq!(scene.obstacles_between([0.0; 3], [0.0; 3]), 0);
    }

    #[test]
    fn yaw_is_clockwise_from_above() {
        let v = yaw_rotate(std::f64::consts::FRAC_PI_2, [1.0, 0.0, 0.0]);
        assert!(v[0].abs() < 1e-12 && (v[1] - 1.0).abs() < 1e-12);
        let up = direction(std::f64::consts::FRAC_PI_2, 0.0);
        assert!((up[2] + 1.0).abs() < 1e-12);
    }
}
