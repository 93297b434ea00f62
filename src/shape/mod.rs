//! Surfaces in the scene: every mesh's triangles placed in world space, in
//! a bounding volume hierarchy per set of objects a kind of ray sees (`obvhs`' compressed wide BVH, built by
//! PLOC: Meister & Bittner 2018, "Parallel Locally-Ordered Clustering for
//! Bounding Volume Hierarchy Construction"; Ylitie, Karras & Laine 2017,
//! "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide
//! BVHs"), with each object's Blender visibility (pbrt-v4's split: shapes
//! here, what a hit means to light in the integrators).
//!
//! Surfaces are opaque to the rays their visibility lets see them
//! ([`RayKind`], Blender's Object > Visibility > Ray Visibility): a ray
//! through the media stops at the first one, so the trackers walk the
//! media only up to it (`t_max`). A scene without meshes has an empty
//! [`Shapes`], whose queries answer at once, so its images are the bits
//! they were before surfaces existed.
//!
//! Intersection is Möller & Trumbore's (1997) test on `f32` world-space
//! triangles stored in the BVH's leaf order (no indirection per test).
//! Rays leaving a surface start a small distance off it along its normal
//! ([`Hit::spawn`]), scaled to the coordinates' magnitude, so that they do
//! not hit the triangle they left.

use glam::{Vec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray as BvhRay, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

/// The kinds of rays, as Blender's ray visibility names them. A ray of a
/// kind sees (and is stopped by) only objects visible to that kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RayKind(u8);

impl RayKind {
    /// Rays from the camera.
    pub const CAMERA: RayKind = RayKind(1);
    /// Shadow rays towards lights, and light on its way from a light
    /// before it first scatters (photons).
    pub const SHADOW: RayKind = RayKind(2);
    /// Rays leaving a diffuse surface.
    pub const DIFFUSE: RayKind = RayKind(4);
    /// Rays leaving a glossy surface.
    pub const GLOSSY: RayKind = RayKind(8);
    /// Rays through a transmissive surface.
    pub const TRANSMISSION: RayKind = RayKind(16);
    /// Rays scattered in a volume (paths and photons after a scattering
    /// event, and the light the media emit).
    pub const VOLUME_SCATTER: RayKind = RayKind(32);
}

/// The kinds of rays that see an object (Blender's ray visibility).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Visibility(u8);

impl Visibility {
    /// Visible to every kind of ray (Blender's default).
    pub const ALL: Visibility = Visibility(63);
    /// Visible to no ray.
    pub const NONE: Visibility = Visibility(0);

    /// This visibility with rays of `kind` seeing it or not.
    pub fn with(self, kind: RayKind, visible: bool) -> Visibility {
        if visible {
            Visibility(self.0 | kind.0)
        } else {
            Visibility(self.0 & !kind.0)
        }
    }
    /// Whether rays of `kind` see it.
    #[inline]
    pub fn sees(self, kind: RayKind) -> bool {
        self.0 & kind.0 != 0
    }
}

/// What an object is to the image beyond being opaque (Blender's Object >
/// Visibility > Mask).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObjectFlags {
    /// A hole in the image: where the camera sees it, colour and alpha 0.
    pub holdout: bool,
    /// Receives shadows for compositing (Cycles' Shadow Catcher pass).
    pub shadow_catcher: bool,
    pub visibility: Visibility,
}

impl Default for ObjectFlags {
    fn default() -> Self {
        Self {
            holdout: false,
            shadow_catcher: false,
            visibility: Visibility::ALL,
        }
    }
}

/// One object (a placed mesh).
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// Its name, for messages.
    pub name: String,
    pub flags: ObjectFlags,
    /// Its triangles.
    pub triangles: usize,
}

/// The nearest surface a ray meets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the ray (its direction unit).
    pub t: f32,
    /// World position.
    pub p: Vec3,
    /// Unit geometric normal, facing the ray's origin.
    pub n: Vec3,
    /// The object hit ([`Shapes::object`]).
    pub object: u32,
    /// The triangle hit, in its object's [`Geometry`].
    pub prim: u32,
    /// Barycentric coordinates of `p` in it (of its second and third
    /// vertices).
    pub bary: Vec2,
}

/// A placed mesh's triangles in world space, and what shading reads at a
/// point of them: normals (world space, one per vertex, or none: the face
/// normal) and texture coordinates (one per vertex, or none).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Geometry {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
}

impl Geometry {
    /// Triangles given by their corners, without normals or texture
    /// coordinates.
    pub fn from_triangles(t: &[[Vec3; 3]]) -> Geometry {
        Geometry {
            positions: t.iter().flatten().copied().collect(),
            triangles: (0..t.len() as u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect(),
            ..Geometry::default()
        }
    }

    /// Bytes kept for shading.
    fn shading_bytes(&self) -> usize {
        self.triangles.capacity() * 12 + self.normals.capacity() * 12 + self.uvs.capacity() * 8
    }
}

/// What shading needs at a [`Hit`]: the shading normal (interpolated from
/// the vertices' normals, on the side the ray came from; the geometric
/// normal where the mesh has none) and the texture coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shading {
    pub n: Vec3,
    pub uv: Vec2,
}

impl Hit {
    /// The origin of a ray leaving the surface towards `w`: `p` moved off
    /// the surface along the normal on `w`'s side, by a distance scaled to
    /// the coordinates' magnitude (float precision of `p` and of the
    /// intersection that found it).
    #[inline]
    pub fn spawn(&self, w: Vec3) -> Vec3 {
        let eps = 1e-4 * self.p.abs().max_element().max(1.0);
        let n = if w.dot(self.n) >= 0.0 {
            self.n
        } else {
            -self.n
        };
        self.p + n * eps
    }
}

/// The surfaces one kind of ray sees, in one BVH.
struct Set {
    bvh: CwBvh,
    /// Triangles in the BVH's leaf order.
    triangles: Vec<Triangle>,
    /// The object of each of `triangles`.
    object_of: Vec<u32>,
    /// The index of each of `triangles` in its object's geometry.
    prim_of: Vec<u32>,
    /// The box around every triangle, for a test before the traversal.
    lo: Vec3A,
    hi: Vec3A,
}

impl Set {
    fn new(tris: &[Triangle], owner: &[u32], prims: &[u32]) -> Set {
        // Each triangle's box padded by a little more than float precision
        // at its coordinates: a flat box (a ground plane's) seen edge-on or
        // along an axis gives an empty interval to the traversal's node
        // tests, and the ray would pass through it.
        let boxes: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                let b = t.aabb();
                let pad = 1e-6 * b.min.abs().max(b.max.abs()).max_element().max(1.0);
                Aabb {
                    min: b.min - Vec3A::splat(pad),
                    max: b.max + Vec3A::splat(pad),
                }
            })
            .collect();
        let bvh = build_cwbvh(
            &boxes,
            BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        let triangles: Vec<Triangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        let object_of = bvh
            .primitive_indices
            .iter()
            .map(|&i| owner[i as usize])
            .collect();
        let prim_of = bvh
            .primitive_indices
            .iter()
            .map(|&i| prims[i as usize])
            .collect();
        let (mut lo, mut hi) = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
        for b in &boxes {
            lo = lo.min(b.min);
            hi = hi.max(b.max);
        }
        Set {
            bvh,
            triangles,
            object_of,
            prim_of,
            lo,
            hi,
        }
    }

    /// Whether `o + t d` can meet the box for `t` in `(0, t_max)` (a slab
    /// test, IEEE infinities for axis-parallel directions).
    #[inline]
    fn may_hit(&self, o: Vec3A, inv: Vec3A, t_max: f32) -> bool {
        let a = (self.lo - o) * inv;
        let b = (self.hi - o) * inv;
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element().min(t_max);
        // NaN (0 · ∞ on a face) counts as a possible hit.
        t0.partial_cmp(&t1) != Some(std::cmp::Ordering::Greater)
    }

    fn memory_bytes(&self) -> usize {
        self.triangles.capacity() * std::mem::size_of::<Triangle>()
            + self.object_of.capacity() * 4
            + self.prim_of.capacity() * 4
            + self.bvh.nodes.capacity() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
            + self.bvh.primitive_indices.capacity() * 4
    }
}

/// `d` with its negative zeros made positive: `obvhs`' traversal takes
/// the sign bit of a −0 component for a direction it does not have, and
/// misses (a ray straight down, (−0, −0, −1), passed through a ground
/// plane).
#[inline]
fn canonical(d: Vec3) -> Vec3A {
    Vec3A::from(d) + Vec3A::ZERO
}

/// The distance along `o + t d` to triangle `tri` for `t` in `(0, t_max)`,
/// or infinity: Möller & Trumbore (1997), "Fast, Minimum Storage
/// Ray/Triangle Intersection", with inclusive edges. (`obvhs`' own test
/// reads a barycentric of −0 as negative, so a ray along an axis, a sun
/// straight overhead, passed through a ground plane.)
#[inline]
fn intersect_triangle(tri: &Triangle, o: Vec3A, d: Vec3A, t_max: f32) -> f32 {
    let e1 = tri.v1 - tri.v0;
    let e2 = tri.v2 - tri.v0;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return f32::INFINITY;
    }
    let inv = 1.0 / det;
    let s = o - tri.v0;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return f32::INFINITY;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return f32::INFINITY;
    }
    let t = e2.dot(q) * inv;
    if t > 0.0 && t < t_max {
        t
    } else {
        f32::INFINITY
    }
}

/// The barycentric coordinates (of `v1` and `v2`) where the ray `o + t d`
/// meets the plane of `tri` (Möller–Trumbore's u and v).
#[inline]
fn barycentric(tri: &Triangle, o: Vec3A, d: Vec3A) -> Vec2 {
    let e1 = tri.v1 - tri.v0;
    let e2 = tri.v2 - tri.v0;
    let p = d.cross(e2);
    let inv = 1.0 / e1.dot(p);
    let s = o - tri.v0;
    let u = s.dot(p) * inv;
    let v = d.dot(s.cross(e1)) * inv;
    Vec2::new(u, v).clamp(Vec2::ZERO, Vec2::ONE)
}

/// The kinds of rays, in the order of [`Shapes`]' table.
const KINDS: [RayKind; 6] = [
    RayKind::CAMERA,
    RayKind::SHADOW,
    RayKind::DIFFUSE,
    RayKind::GLOSSY,
    RayKind::TRANSMISSION,
    RayKind::VOLUME_SCATTER,
];

/// Every surface of a scene: per kind of ray, a BVH of the objects that
/// kind sees. Kinds that see the same objects share one (with Blender's
/// default visibility there is a single BVH); an object hidden from a kind
/// costs that kind's rays nothing.
#[derive(Default)]
pub struct Shapes {
    objects: Vec<Object>,
    /// Each object's normals and texture coordinates, for shading.
    geometry: Vec<Geometry>,
    /// The BVHs, one per distinct set of visible objects.
    sets: Vec<Set>,
    /// For each of [`KINDS`], its BVH in `sets` (none when it sees no
    /// surface).
    of_kind: [Option<u8>; 6],
    /// Whether any object catches shadows.
    catcher: bool,
    /// Each object's world-space bounds (none without triangles).
    bounds: Vec<Option<(Vec3, Vec3)>>,
}

impl std::fmt::Debug for Shapes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Shapes")
            .field("objects", &self.objects)
            .field("bvhs", &self.sets.len())
            .finish()
    }
}

/// Bytes per triangle that [`Shapes`] keeps (triangle, object index, BVH
/// node share and index) and that reading and building take at their peak
/// beside them: measured on a 1 M-triangle mesh (`cargo bench --bench
/// meshes`: 400 bytes a triangle from binary PLY, 375 from OBJ), for the
/// memory check before a render.
pub const BYTES_PER_TRIANGLE: u64 = 440;

impl Shapes {
    /// No surfaces.
    pub fn empty() -> Shapes {
        Shapes::default()
    }

    /// The objects and their world-space geometry.
    pub fn new(parts: Vec<(Object, Geometry)>) -> Shapes {
        let objects: Vec<Object> = parts.iter().map(|p| p.0.clone()).collect();
        let catcher = objects.iter().any(|o| o.flags.shadow_catcher);
        let mut sets = Vec::new();
        let mut of_kind = [None; 6];
        // The objects each kind sees (with triangles), and a BVH per
        // distinct such set.
        let mut seen: Vec<Vec<usize>> = Vec::new();
        for (k, kind) in KINDS.iter().enumerate() {
            let visible: Vec<usize> = parts
                .iter()
                .enumerate()
                .filter(|(_, (o, g))| o.flags.visibility.sees(*kind) && !g.triangles.is_empty())
                .map(|(i, _)| i)
                .collect();
            if visible.is_empty() {
                continue;
            }
            if let Some(j) = seen.iter().position(|v| *v == visible) {
                of_kind[k] = Some(j as u8);
                continue;
            }
            let mut tris = Vec::new();
            let mut owner = Vec::new();
            let mut prims = Vec::new();
            for &i in &visible {
                let g = &parts[i].1;
                tris.extend(g.triangles.iter().map(|t| {
                    let [a, b, c] = t.map(|k| Vec3A::from(g.positions[k as usize]));
                    Triangle {
                        v0: a,
                        v1: b,
                        v2: c,
                    }
                }));
                owner.extend(std::iter::repeat_n(i as u32, g.triangles.len()));
                prims.extend(0..g.triangles.len() as u32);
            }
            sets.push(Set::new(&tris, &owner, &prims));
            of_kind[k] = Some(seen.len() as u8);
            seen.push(visible);
        }
        let bounds = parts
            .iter()
            .map(|(_, g)| {
                let mut used = g
                    .triangles
                    .iter()
                    .flatten()
                    .map(|&k| g.positions[k as usize]);
                let first = used.next()?;
                Some(used.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
            })
            .collect();
        let geometry = parts
            .into_iter()
            .map(|(_, g)| Geometry {
                positions: Vec::new(),
                ..g
            })
            .collect();
        Shapes {
            objects,
            geometry,
            sets,
            of_kind,
            catcher,
            bounds,
        }
    }

    /// Object `i`'s world-space bounds (none without triangles).
    pub fn object_bounds(&self, i: usize) -> Option<(Vec3, Vec3)> {
        self.bounds[i]
    }

    /// The shading normal and texture coordinates at `hit`.
    #[inline]
    pub fn shading(&self, hit: &Hit) -> Shading {
        let g = &self.geometry[hit.object as usize];
        let t = g.triangles[hit.prim as usize].map(|k| k as usize);
        let (b1, b2) = (hit.bary.x, hit.bary.y);
        let b0 = 1.0 - b1 - b2;
        let n = if g.normals.is_empty() {
            hit.n
        } else {
            let n = (g.normals[t[0]] * b0 + g.normals[t[1]] * b1 + g.normals[t[2]] * b2)
                .normalize_or_zero();
            if n == Vec3::ZERO {
                hit.n
            } else if n.dot(hit.n) < 0.0 {
                -n
            } else {
                n
            }
        };
        let uv = if g.uvs.is_empty() {
            Vec2::ZERO
        } else {
            g.uvs[t[0]] * b0 + g.uvs[t[1]] * b1 + g.uvs[t[2]] * b2
        };
        Shading { n, uv }
    }

    /// Whether no ray can meet a surface.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.sets.is_empty()
    }
    /// The objects, in scene order.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }
    /// Object `i` of a [`Hit`].
    pub fn object(&self, i: u32) -> &Object {
        &self.objects[i as usize]
    }
    /// Whether any object is a shadow catcher.
    pub fn has_catcher(&self) -> bool {
        self.catcher
    }
    /// Triangles in the scene (each once, whatever the BVHs share).
    pub fn triangles(&self) -> usize {
        self.objects.iter().map(|o| o.triangles).sum()
    }
    /// Bytes the surfaces take.
    pub fn memory_bytes(&self) -> usize {
        self.sets.iter().map(Set::memory_bytes).sum::<usize>()
            + self
                .geometry
                .iter()
                .map(Geometry::shading_bytes)
                .sum::<usize>()
    }

    #[inline]
    fn set(&self, kind: RayKind) -> Option<&Set> {
        let k = kind.0.trailing_zeros() as usize;
        self.of_kind[k].map(|i| &self.sets[i as usize])
    }

    /// The nearest surface along `o + t d` (`d` unit) with `t` in
    /// `(0, t_max)` that rays of `kind` see.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f32, kind: RayKind) -> Option<Hit> {
        self.intersect_where(o, d, t_max, kind, |_| true)
    }

    /// [`Self::intersect`] among the surfaces rays of `kind` see that
    /// `keep` accepts.
    #[inline]
    pub fn intersect_where(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        kind: RayKind,
        keep: impl Fn(&ObjectFlags) -> bool,
    ) -> Option<Hit> {
        let set = self.set(kind)?;
        let (oa, da) = (Vec3A::from(o), canonical(d));
        if !set.may_hit(oa, da.recip(), t_max) {
            return None;
        }
        let ray = BvhRay::new(oa, da, 0.0, t_max);
        let mut hit = RayHit::none();
        let found = set.bvh.ray_traverse(ray, &mut hit, |r, id| {
            if !keep(&self.objects[set.object_of[id] as usize].flags) {
                return f32::INFINITY;
            }
            intersect_triangle(&set.triangles[id], r.origin, r.direction, r.tmax)
        });
        if !found {
            return None;
        }
        let id = hit.primitive_id as usize;
        let tri = &set.triangles[id];
        let n = Vec3::from(tri.compute_normal());
        Some(Hit {
            t: hit.t,
            p: o + d * hit.t,
            n: if n.dot(d) > 0.0 { -n } else { n },
            object: set.object_of[id],
            prim: set.prim_of[id],
            bary: barycentric(tri, oa, da),
        })
    }

    /// Whether a surface that rays of `kind` see lies along `o + t d` with
    /// `t` in `(0, t_max)` (a shadow ray: any hit will do).
    #[inline]
    pub fn occluded(&self, o: Vec3, d: Vec3, t_max: f32, kind: RayKind) -> bool {
        self.occluded_where(o, d, t_max, kind, |_| true)
    }

    /// [`Self::occluded`] among the surfaces rays of `kind` see that `keep`
    /// accepts.
    #[inline]
    pub fn occluded_where(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        kind: RayKind,
        keep: impl Fn(&ObjectFlags) -> bool,
    ) -> bool {
        let Some(set) = self.set(kind) else {
            return false;
        };
        let (oa, da) = (Vec3A::from(o), canonical(d));
        if !set.may_hit(oa, da.recip(), t_max) {
            return false;
        }
        let ray = BvhRay::new(oa, da, 0.0, t_max);
        !set.bvh.ray_traverse_miss(ray, |r, id| {
            if !keep(&self.objects[set.object_of[id] as usize].flags) {
                return f32::INFINITY;
            }
            intersect_triangle(&set.triangles[id], r.origin, r.direction, r.tmax)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f32, flags: ObjectFlags) -> (Object, Geometry) {
        let (a, b, c, d) = (
            Vec3::new(-1.0, -1.0, z),
            Vec3::new(1.0, -1.0, z),
            Vec3::new(1.0, 1.0, z),
            Vec3::new(-1.0, 1.0, z),
        );
        (
            Object {
                name: format!("square at {z}"),
                flags,
                triangles: 2,
            },
            Geometry::from_triangles(&[[a, b, c], [a, c, d]]),
        )
    }

    /// The nearest surface a ray's kind sees: one invisible to camera rays
    /// is passed by them and stops shadow rays; the normal faces the ray.
    #[test]
    fn rays_see_what_their_kind_sees() {
        let hidden = ObjectFlags {
            visibility: Visibility::ALL.with(RayKind::CAMERA, false),
            ..ObjectFlags::default()
        };
        let s = Shapes::new(vec![
            square(1.0, hidden),
            square(-1.0, ObjectFlags::default()),
        ]);
        let o = Vec3::new(0.2, 0.1, 3.0);
        let d = -Vec3::Z;
        let h = s.intersect(o, d, f32::INFINITY, RayKind::CAMERA).unwrap();
        assert_eq!(h.object, 1);
        assert!((h.t - 4.0).abs() < 1e-5);
        assert_eq!(h.n, Vec3::Z);
        let h = s.intersect(o, d, f32::INFINITY, RayKind::SHADOW).unwrap();
        assert_eq!(h.object, 0);
        assert!((h.t - 2.0).abs() < 1e-5);
        assert!(s.occluded(o, d, 2.5, RayKind::SHADOW));
        assert!(!s.occluded(o, d, 1.5, RayKind::SHADOW));
        assert!(!s.occluded(o, d, 3.5, RayKind::CAMERA));
        // From below, the normal faces down; a ray leaving the surface
        // does not meet it again.
        let h = s
            .intersect(
                Vec3::new(0.3, 0.3, -5.0),
                Vec3::Z,
                f32::INFINITY,
                RayKind::CAMERA,
            )
            .unwrap();
        assert_eq!(h.n, -Vec3::Z);
        let up = s.intersect(h.spawn(-Vec3::Z), -Vec3::Z, f32::INFINITY, RayKind::CAMERA);
        assert!(up.is_none());
        assert!(Shapes::empty()
            .intersect(o, d, f32::INFINITY, RayKind::CAMERA)
            .is_none());
    }

    /// Rays along an axis, from either side, with negative zeros in their
    /// direction (−Vec3::Z is (−0, −0, −1)) or through the edge two
    /// triangles share, hit a lone flat square: `obvhs`' own triangle test
    /// and its traversal of a −0 direction both missed it.
    #[test]
    fn axis_rays_hit_a_flat_square() {
        let s = Shapes::new(vec![square(0.5, ObjectFlags::default())]);
        for (o, d) in [
            (Vec3::new(0.2, 0.1, 3.0), -Vec3::Z),
            (Vec3::new(0.3, 0.3, -5.0), Vec3::Z),
            (Vec3::new(0.0, 0.0, -5.0), Vec3::Z),
            (Vec3::new(-0.25, -0.25, 2.0), -Vec3::Z),
            (Vec3::new(0.2, 3.0, 0.5), -Vec3::Y),
        ] {
            assert!(
                s.intersect(o, d, f32::INFINITY, RayKind::SHADOW).is_some() || d == -Vec3::Y,
                "{o} {d}"
            );
            assert!(s.occluded(o, d, f32::INFINITY, RayKind::SHADOW) || d == -Vec3::Y);
        }
    }
}
