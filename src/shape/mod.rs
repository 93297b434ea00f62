//! Surfaces in the scene: every mesh's triangles placed in world space, in
//! one bounding volume hierarchy (`obvhs`' compressed wide BVH, built by
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

use glam::{Vec3, Vec3A};
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
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

/// Every surface of a scene in one BVH.
#[derive(Default)]
pub struct Shapes {
    objects: Vec<Object>,
    /// The BVH (none without triangles).
    bvh: Option<CwBvh>,
    /// Triangles in the BVH's leaf order.
    triangles: Vec<Triangle>,
    /// The object of each of `triangles`.
    object_of: Vec<u32>,
    /// Whether any object catches shadows.
    catcher: bool,
}

impl std::fmt::Debug for Shapes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Shapes")
            .field("objects", &self.objects)
            .field("triangles", &self.triangles.len())
            .finish()
    }
}

/// Bytes per triangle that [`Shapes`] keeps (triangle, object index, BVH
/// node share and index) and that its build takes at its peak beside them:
/// measured on a 1 M-triangle mesh (`cargo bench --bench meshes`), for the
/// memory check before a render.
pub const BYTES_PER_TRIANGLE: u64 = 260;

impl Shapes {
    /// No surfaces.
    pub fn empty() -> Shapes {
        Shapes::default()
    }

    /// The objects and their world-space triangles, in one BVH.
    pub fn new(parts: Vec<(Object, Vec<[Vec3; 3]>)>) -> Shapes {
        let mut objects = Vec::with_capacity(parts.len());
        let mut tris = Vec::new();
        let mut owner = Vec::new();
        for (i, (o, t)) in parts.into_iter().enumerate() {
            tris.extend(t.iter().map(|v| Triangle {
                v0: v[0].into(),
                v1: v[1].into(),
                v2: v[2].into(),
            }));
            owner.extend(std::iter::repeat_n(i as u32, t.len()));
            objects.push(o);
        }
        let catcher = objects.iter().any(|o| o.flags.shadow_catcher);
        if tris.is_empty() {
            return Shapes {
                objects,
                catcher,
                ..Shapes::default()
            };
        }
        let bvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        let triangles = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        let object_of = bvh
            .primitive_indices
            .iter()
            .map(|&i| owner[i as usize])
            .collect();
        Shapes {
            objects,
            bvh: Some(bvh),
            triangles,
            object_of,
            catcher,
        }
    }

    /// Whether the scene has no surface.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.bvh.is_none()
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
    /// Triangles in the BVH.
    pub fn triangles(&self) -> usize {
        self.triangles.len()
    }
    /// Bytes the surfaces take.
    pub fn memory_bytes(&self) -> usize {
        self.triangles.capacity() * std::mem::size_of::<Triangle>()
            + self.object_of.capacity() * 4
            + self.bvh.as_ref().map_or(0, |b| {
                b.nodes.capacity() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
                    + b.primitive_indices.capacity() * 4
            })
    }

    /// The nearest surface along `o + t d` (`d` unit) with `t` in
    /// `(0, t_max)` that rays of `kind` see.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f32, kind: RayKind) -> Option<Hit> {
        self.intersect_where(o, d, t_max, |f| f.visibility.sees(kind))
    }

    /// [`Self::intersect`] for the surfaces `keep` accepts.
    #[inline]
    pub fn intersect_where(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        keep: impl Fn(&ObjectFlags) -> bool,
    ) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let ray = BvhRay::new(Vec3A::from(o), Vec3A::from(d), 0.0, t_max);
        let mut hit = RayHit::none();
        let found = bvh.ray_traverse(ray, &mut hit, |r, id| {
            let obj = self.object_of[id];
            if !keep(&self.objects[obj as usize].flags) {
                return f32::INFINITY;
            }
            let t = self.triangles[id].intersect(r);
            if t > 0.0 {
                t
            } else {
                f32::INFINITY
            }
        });
        if !found {
            return None;
        }
        let id = hit.primitive_id as usize;
        let tri = &self.triangles[id];
        let n = Vec3::from(tri.compute_normal());
        Some(Hit {
            t: hit.t,
            p: o + d * hit.t,
            n: if n.dot(d) > 0.0 { -n } else { n },
            object: self.object_of[id],
        })
    }

    /// Whether a surface that rays of `kind` see lies along `o + t d` with
    /// `t` in `(0, t_max)` (a shadow ray: any hit will do).
    #[inline]
    pub fn occluded(&self, o: Vec3, d: Vec3, t_max: f32, kind: RayKind) -> bool {
        self.occluded_where(o, d, t_max, |f| f.visibility.sees(kind))
    }

    /// [`Self::occluded`] for the surfaces `keep` accepts.
    #[inline]
    pub fn occluded_where(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        keep: impl Fn(&ObjectFlags) -> bool,
    ) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let ray = BvhRay::new(Vec3A::from(o), Vec3A::from(d), 0.0, t_max);
        !bvh.ray_traverse_miss(ray, |r, id| {
            if !keep(&self.objects[self.object_of[id] as usize].flags) {
                return f32::INFINITY;
            }
            let t = self.triangles[id].intersect(r);
            if t > 0.0 {
                t
            } else {
                f32::INFINITY
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f32, flags: ObjectFlags) -> (Object, Vec<[Vec3; 3]>) {
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
            vec![[a, b, c], [a, c, d]],
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
}
