// The renderer's deterministic path for the models (src/render/mod.rs): one thread per pixel of each stack's image
// (a batch of stacks in one dispatch), and
// Σ f(l, v) max(0, n·l) E over directional and point lights, f from the model's eval_pair. Composed after
// optics.wgsl, a model's shader (whose `out` serves as each pixel's scratch), scene.wgsl and mesh.wgsl.

// Σ f(l, v) max(0, n·l) E at a hit seen along d, f from the model's eval_pair and transport_fit (scratch at `base`),
// with the per-element inputs' textures at the hit's uv.
fn shade_lights(hit: Hit, d: vec3<f32>, base: u32) -> vec3<f32> {
    load_texture_inputs(hit.uv);
    var rgb = vec3<f32>(0.0);
    let b = cross(hit.n, hit.t);
    let wo = vec3<f32>(dot(-d, hit.t), dot(-d, b), dot(-d, hit.n));
    for (var k = 0u; k < rp.lights; k++) {
        let light = incident(k, hit.p);
        let l = light[0];
        let wi = vec3<f32>(dot(l, hit.t), dot(l, b), dot(l, hit.n));
        if wi.z > 0.0 && wo.z > 0.0 {
            eval_fitted(wi, wo, base);
            rgb += vec3<f32>(out[base], out[base + 1u], out[base + 2u]) * wi.z * light[1];
        }
    }
    return rgb;
}

// The pixel of thread t (of its stack's image), with `params` set to that stack's; rp.width·rp.height·rp.stacks
// (none: past the batch's last image).
fn begin(t: u32) -> u32 {
    let pixels = rp.width * rp.height;
    if t >= pixels * rp.stacks {
        return pixels;
    }
    params = stack_params[t / pixels];
    fit = fit_stacks[t / pixels];
    return t % pixels;
}

// The sphere or the plane.
@compute @workgroup_size(64)
fn render(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = thread_index(gid, groups);
    let px = begin(t);
    if px == rp.width * rp.height {
        return;
    }
    let ray = camera_ray(px);
    let hit = intersect(ray[0], ray[1]);
    var rgb = vec3<f32>(0.0);
    if hit.found {
        rgb = shade_lights(hit, ray[1], t * params.channels);
    }
    store(t, rgb);
}

// A mesh: the surface the camera pass found at the pixel.
@compute @workgroup_size(64)
fn render_mesh(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = thread_index(gid, groups);
    let px = begin(t);
    if px == rp.width * rp.height {
        return;
    }
    let ray = camera_ray(px);
    let d = ray[1];
    let hit = camera_surface(px, ray[0], d);
    var rgb = vec3<f32>(0.0);
    if hit.found {
        rgb = shade_lights(hit, d, t * params.channels);
    }
    store(t, rgb);
}
