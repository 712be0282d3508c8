//! Triangle meshes for the renderer: per-vertex positions, normals, uv and (optionally) tangents, a bounding volume
//! hierarchy over the triangles (median split on the widest centroid axis, pbrt-v4 §7.3 in its simplest form) and
//! the ray–triangle test of Möller and Trumbore 1997. OBJ files load through the `tobj` crate.

use super::Hit;
use crate::error::{value_error, Result};
use glam::DVec3;

pub struct Mesh {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    uvs: Vec<[f64; 2]>,
    /// Given, or along +u from the uv layout (`uv_tangents`).
    tangents: Vec<DVec3>,
    triangles: Vec<[usize; 3]>,
    nodes: Vec<Node>,
}

/// A BVH node: its bounds, and either two children (`first` is the right child; the left one follows the node) or
/// `count` > 0 triangles from `first` in the reordered triangle list.
struct Node {
    lo: DVec3,
    hi: DVec3,
    first: usize,
    count: usize,
}

const LEAF: usize = 4;

impl Mesh {
    /// A mesh from per-vertex arrays and triangles (vertex indices); checks the indices and lengths.
    pub fn new(
        positions: Vec<DVec3>,
        normals: Vec<DVec3>,
        uvs: Vec<[f64; 2]>,
        tangents: Option<Vec<DVec3>>,
        triangles: Vec<[usize; 3]>,
    ) -> Result<Mesh> {
        let n = positions.len();
        if normals.len() != n || uvs.len() != n || tangents.as_ref().is_some_and(|t| t.len() != n) {
            return value_error("mesh: normals, uvs and tangents must have one row per vertex");
        }
        if triangles.is_empty() {
            return value_error("mesh: triangles must not be empty");
        }
        if let Some(t) = triangles.iter().find(|t| t.iter().any(|&i| i >= n)) {
            return value_error(format!("mesh: triangle {t:?} indexes a vertex outside [0, {n})"));
        }
        let tangents = tangents.unwrap_or_else(|| uv_tangents(&positions, &uvs, &triangles));
        let mut mesh = Mesh { positions, normals, uvs, tangents, triangles, nodes: Vec::new() };
        let count = mesh.triangles.len();
        mesh.build(0, count);
        Ok(mesh)
    }

    fn bounds(&self, tris: &[[usize; 3]]) -> (DVec3, DVec3) {
        tris.iter().flatten().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &i| {
            (lo.min(self.positions[i]), hi.max(self.positions[i]))
        })
    }

    /// Builds the subtree of triangles first..first + count, returning its node index.
    fn build(&mut self, first: usize, count: usize) -> usize {
        let (lo, hi) = self.bounds(&self.triangles[first..first + count]);
        let node = self.nodes.len();
        self.nodes.push(Node { lo, hi, first, count });
        if count <= LEAF {
            return node;
        }
        let centroid = |t: &[usize; 3], p: &[DVec3]| (p[t[0]] + p[t[1]] + p[t[2]]) / 3.0;
        let (clo, chi) = self.triangles[first..first + count]
            .iter()
            .map(|t| centroid(t, &self.positions))
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), c| (lo.min(c), hi.max(c)));
        let axis = (chi - clo).max_position();
        let positions = &self.positions;
        let mid = count / 2;
        self.triangles[first..first + count]
            .select_nth_unstable_by(mid, |a, b| centroid(a, positions)[axis].total_cmp(&centroid(b, positions)[axis]));
        self.build(first, mid);
        let right = self.build(first + mid, count - mid);
        self.nodes[node].first = right;
        self.nodes[node].count = 0;
        node
    }

    /// The nearest hit of the ray o + s d (s > 0), with interpolated normal, tangent and uv.
    pub fn intersect(&self, o: DVec3, d: DVec3) -> Option<Hit> {
        let inv = d.recip();
        let mut best: Option<(f64, usize, f64, f64)> = None;
        let mut stack = vec![0usize];
        while let Some(k) = stack.pop() {
            let node = &self.nodes[k];
            let far = best.map_or(f64::INFINITY, |b| b.0);
            if !slab_test(node.lo, node.hi, o, inv, far) {
                continue;
            }
            if node.count == 0 {
                stack.extend([k + 1, node.first]);
                continue;
            }
            for (j, tri) in self.triangles[node.first..node.first + node.count].iter().enumerate() {
                let p = tri.map(|i| self.positions[i]);
                if let Some((s, b1, b2)) = ray_triangle(o, d, p) {
                    if s < best.map_or(f64::INFINITY, |b| b.0) {
                        best = Some((s, node.first + j, b1, b2));
                    }
                }
            }
        }
        let (_, k, b1, b2) = best?;
        let mut hit = self.surface(k, [1.0 - b1 - b2, b1, b2])?;
        if hit.n.dot(d) > 0.0 {
            hit.n = -hit.n; // seen from behind: shade the side the ray arrives at
        }
        Some(hit)
    }

    /// The point of triangle k at barycentrics b: position, normal, tangent (Gram–Schmidt against the normal; ŷ × n
    /// where the tangents vanish) and uv, interpolated.
    fn surface(&self, k: usize, b: [f64; 3]) -> Option<Hit> {
        let tri = self.triangles[k];
        let lerp3 = |v: &[DVec3]| b[0] * v[tri[0]] + b[1] * v[tri[1]] + b[2] * v[tri[2]];
        let n = lerp3(&self.normals).try_normalize()?;
        let t = lerp3(&self.tangents);
        let t = (t - t.dot(n) * n)
            .try_normalize()
            .or_else(|| DVec3::Y.cross(n).try_normalize())
            .unwrap_or_else(|| crate::sampling::orthonormal_basis(n).0);
        let uv = std::array::from_fn(|c| (0..3).map(|j| b[j] * self.uvs[tri[j]][c]).sum());
        Some(Hit { p: lerp3(&self.positions), n, t, uv })
    }

    /// The mesh for the GPU (gpu/shaders/mesh.wgsl): per vertex (position, normal, uv, tangent) as 11 float32, and
    /// the triangles' vertex indices.
    pub fn gpu_arrays(&self) -> (Vec<f32>, Vec<u32>) {
        let mut rows = Vec::with_capacity(11 * self.positions.len());
        for k in 0..self.positions.len() {
            let (p, n, t) = (self.positions[k], self.normals[k], self.tangents[k]);
            rows.extend(
                [p.x, p.y, p.z, n.x, n.y, n.z, self.uvs[k][0], self.uvs[k][1], t.x, t.y, t.z].map(|x| x as f32),
            );
        }
        (rows, self.triangles.iter().flatten().map(|&i| i as u32).collect())
    }

    /// The mesh rasterized in uv space at width x height texels: the surface point at each texel centre
    /// ((i + ½)/W, (j + ½)/H) that a triangle covers, None elsewhere (the light map of Oat 2006, step 2).
    pub fn rasterize_uv(&self, width: usize, height: usize) -> Vec<Option<Hit>> {
        let mut out: Vec<Option<Hit>> = vec![None; width * height];
        for k in 0..self.triangles.len() {
            let q =
                self.triangles[k].map(|i| [self.uvs[i][0] * width as f64 - 0.5, self.uvs[i][1] * height as f64 - 0.5]);
            let area = (q[1][0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[2][0] - q[0][0]) * (q[1][1] - q[0][1]);
            if area.abs() < 1e-12 {
                continue;
            }
            let span = |c: usize, n: usize| {
                let lo = q.iter().map(|p| p[c]).fold(f64::INFINITY, f64::min).ceil().max(0.0) as usize;
                let hi = q.iter().map(|p| p[c]).fold(f64::NEG_INFINITY, f64::max).floor();
                (lo, if hi < 0.0 { 0 } else { (hi as usize + 1).min(n) })
            };
            let ((i0, i1), (j0, j1)) = (span(0, width), span(1, height));
            for j in j0..j1 {
                for i in i0..i1 {
                    let (x, y) = (i as f64, j as f64);
                    let edge =
                        |a: [f64; 2], b: [f64; 2]| ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / area;
                    let b = [edge(q[1], q[2]), edge(q[2], q[0]), edge(q[0], q[1])];
                    if b.iter().all(|&w| w >= -1e-9) {
                        out[j * width + i] = self.surface(k, b).or(out[j * width + i]);
                    }
                }
            }
        }
        out
    }
}

/// Per-vertex tangents along +u from the uv layout (Lengyel 2001): each triangle's ∂p/∂u, summed over the
/// triangles that share the vertex. Zero where the uv map is degenerate.
fn uv_tangents(positions: &[DVec3], uvs: &[[f64; 2]], triangles: &[[usize; 3]]) -> Vec<DVec3> {
    let mut t = vec![DVec3::ZERO; positions.len()];
    for tri in triangles {
        let (e1, e2) = (positions[tri[1]] - positions[tri[0]], positions[tri[2]] - positions[tri[0]]);
        let (du1, dv1) = (uvs[tri[1]][0] - uvs[tri[0]][0], uvs[tri[1]][1] - uvs[tri[0]][1]);
        let (du2, dv2) = (uvs[tri[2]][0] - uvs[tri[0]][0], uvs[tri[2]][1] - uvs[tri[0]][1]);
        let det = du1 * dv2 - du2 * dv1;
        if det.abs() > 1e-15 {
            let dpdu = ((e1 * dv2 - e2 * dv1) / det).normalize_or_zero();
            tri.iter().for_each(|&i| t[i] += dpdu);
        }
    }
    t
}

/// Whether the ray o + s d (inv = 1/d) meets the box [lo, hi] at some s in (0, far) (Kay and Kajiya 1986).
fn slab_test(lo: DVec3, hi: DVec3, o: DVec3, inv: DVec3, far: f64) -> bool {
    let (a, b) = ((lo - o) * inv, (hi - o) * inv);
    let (near, exit) = (a.min(b).max_element().max(0.0), a.max(b).min_element().min(far));
    near <= exit
}

/// Möller–Trumbore 1997: distance s > 0 and barycentrics (b1, b2) of the ray's hit with the triangle p.
fn ray_triangle(o: DVec3, d: DVec3, p: [DVec3; 3]) -> Option<(f64, f64, f64)> {
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let q = d.cross(e2);
    let det = e1.dot(q);
    if det.abs() < 1e-14 {
        return None;
    }
    let r = o - p[0];
    let b1 = r.dot(q) / det;
    let c = r.cross(e1);
    let b2 = d.dot(c) / det;
    let s = e2.dot(c) / det;
    (b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0 && s > 1e-9).then_some((s, b1, b2))
}

/// Per-vertex arrays of an OBJ file's models, merged: positions, normals (empty if the file has none), uvs (empty
/// if none) and triangles.
pub type ObjArrays = (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[f64; 2]>, Vec<[usize; 3]>);

/// Loads an OBJ file (triangulated, one index per vertex).
pub fn read_obj(path: &str) -> Result<ObjArrays> {
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let models = match tobj::load_obj(path, &options) {
        Ok((models, _materials)) => models,
        Err(e) => return value_error(format!("path: cannot read {path:?} as OBJ: {e}")),
    };
    let (mut p, mut n, mut uv, mut tris) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for m in &models {
        let mesh = &m.mesh;
        let base = p.len();
        let count = mesh.positions.len() / 3;
        p.extend(mesh.positions.chunks_exact(3).map(|c| [c[0] as f64, c[1] as f64, c[2] as f64]));
        if mesh.normals.len() == 3 * count {
            n.extend(mesh.normals.chunks_exact(3).map(|c| [c[0] as f64, c[1] as f64, c[2] as f64]));
        }
        if mesh.texcoords.len() == 2 * count {
            uv.extend(mesh.texcoords.chunks_exact(2).map(|c| [c[0] as f64, 1.0 - c[1] as f64]));
        }
        tris.extend(mesh.indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| base + t[k] as usize)));
    }
    if n.len() != p.len() {
        n.clear();
    }
    if uv.len() != p.len() {
        uv.clear();
    }
    Ok((p, n, uv, tris))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UV sphere of `n` x 2n quads (triangulated), normals = positions.
    fn sphere(n: usize) -> Mesh {
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=2 * n {
                let (th, ph) = (std::f64::consts::PI * j as f64 / n as f64, std::f64::consts::PI * i as f64 / n as f64);
                p.push(DVec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()));
            }
        }
        let idx = |i: usize, j: usize| j * (2 * n + 1) + i;
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..2 * n {
                tris.push([idx(i, j), idx(i + 1, j), idx(i, j + 1)]);
                tris.push([idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)]);
            }
        }
        let uv = vec![[0.0; 2]; p.len()];
        Mesh::new(p.clone(), p, uv, None, tris).unwrap()
    }

    #[test]
    fn bvh_finds_the_nearest_triangle_as_brute_force_does() {
        let mesh = sphere(24);
        let mut rng = crate::sampling::Rng::new(9, 0);
        for _ in 0..500 {
            let o = DVec3::new(rng.uniform() * 2.0 - 1.0, rng.uniform() * 2.0 - 1.0, 3.0);
            let d = (DVec3::new(rng.uniform() - 0.5, rng.uniform() - 0.5, 0.0) * 0.5 - o).normalize();
            let brute = mesh
                .triangles
                .iter()
                .filter_map(|t| ray_triangle(o, d, t.map(|i| mesh.positions[i])).map(|h| h.0))
                .fold(f64::INFINITY, f64::min);
            match mesh.intersect(o, d) {
                Some(hit) => {
                    assert!(((hit.p - o).length() - brute).abs() < 1e-9, "{} vs {brute}", (hit.p - o).length())
                }
                None => assert!(brute.is_infinite()),
            }
        }
    }

    #[test]
    fn bad_meshes_are_refused() {
        let p = vec![DVec3::ZERO, DVec3::X, DVec3::Y];
        assert!(Mesh::new(p.clone(), p.clone(), vec![[0.0; 2]; 3], None, vec![[0, 1, 3]]).is_err());
        assert!(Mesh::new(p.clone(), p.clone(), vec![[0.0; 2]; 2], None, vec![[0, 1, 2]]).is_err());
        assert!(Mesh::new(p.clone(), p, vec![[0.0; 2]; 3], None, vec![]).is_err());
    }
}
