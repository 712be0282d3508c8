// The mesh rasterized into visibility targets (triangle index, b1, b2, 1): in uv space for Oat's light map (the uv
// as positions, the last triangle over a texel wins, as in Mesh::rasterize_uv) and through the camera (the nearest
// by depth, as Scene::intersect finds it). Composed after optics.wgsl, scene.wgsl and mesh.wgsl.

struct Raster {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) triangle: u32,
    @location(1) barycentric: vec3<f32>,
}

fn corner(i: u32, position: vec4<f32>) -> Raster {
    var r: Raster;
    r.position = position;
    r.triangle = i / 3u;
    r.barycentric = vec3<f32>(f32(i % 3u == 0u), f32(i % 3u == 1u), f32(i % 3u == 2u));
    return r;
}

// Texel (i, j) of a target is centred at uv ((i + ½)/W, (j + ½)/H): NDC x = 2u − 1, y = 1 − 2v.
@vertex
fn uv_vertex(@builtin(vertex_index) i: u32) -> Raster {
    let uv = vertex_uv(triangles[i]);
    return corner(i, vec4<f32>(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 0.5, 1.0));
}

// Scene::ray inverted: image point (x, y) of the orthographic contract (depth (10 − z)/1000, the viewer at z = 10)
// or of the pinhole, whose ray is normalize(forward + x right + y up) (depth 1 − 10⁻³/w, w the distance along
// forward).
@vertex
fn camera_vertex(@builtin(vertex_index) i: u32) -> Raster {
    let p = vertex_vec3(triangles[i], 0u);
    if rp.camera == 1u {
        let rel = p - rp.origin.xyz;
        let w = dot(rel, rp.forward.xyz);
        let x = dot(rel, rp.right.xyz) / dot(rp.right.xyz, rp.right.xyz);
        let y = dot(rel, rp.up.xyz) / dot(rp.up.xyz, rp.up.xyz);
        return corner(i, vec4<f32>(x, y, w - 1e-3, w));
    }
    return corner(i, vec4<f32>(p.x, p.y, (10.0 - p.z) / 1000.0, 1.0));
}

@fragment
fn visibility(r: Raster) -> @location(0) vec4<f32> {
    return vec4<f32>(f32(r.triangle), r.barycentric.y, r.barycentric.z, 1.0);
}
