// The renderer's deterministic path for the models (src/render/mod.rs): one thread per pixel, and
// Σ f(l, v) max(0, n·l) E over directional and point lights, f from the model's eval_pair. Composed after
// optics.wgsl, a model's shader (whose `out` serves as each pixel's scratch) and scene.wgsl.

@compute @workgroup_size(64)
fn render(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let px = thread_index(gid, groups);
    if px >= rp.width * rp.height {
        return;
    }
    let ray = camera_ray(px);
    let d = ray[1];
    let hit = intersect(ray[0], d);
    var rgb = vec3<f32>(0.0);
    if hit.found {
        let b = cross(hit.n, hit.t);
        let wo = vec3<f32>(dot(-d, hit.t), dot(-d, b), dot(-d, hit.n));
        let base = px * params.channels;
        for (var k = 0u; k < rp.lights; k++) {
            let light = incident(k, hit.p);
            let l = light[0];
            let wi = vec3<f32>(dot(l, hit.t), dot(l, b), dot(l, hit.n));
            if wi.z > 0.0 && wo.z > 0.0 {
                eval_pair(wi, wo, base);
                rgb += vec3<f32>(out[base], out[base + 1u], out[base + 2u]) * wi.z * light[1];
            }
        }
    }
    image[3u * px] = rgb.x;
    image[3u * px + 1u] = rgb.y;
    image[3u * px + 2u] = rgb.z;
}
