// The per-element inputs of a model (its catalogue's InputSpec order: weidlich_wilkie's flake_normal, distance and
// mask) for the current thread, as textures: the per-element queries give input j of element i as texel i of a one-row
// texture, the renderer as a texture over the surface's uv (render::Texture::lookup, the nearest texel, wrapping). A
// texture of 0 components was not given. Composed after optics.wgsl, before the model, which reads `input` and
// `input_given`; queries.wgsl, render.wgsl and env.wgsl load them.

const MAX_MODEL_INPUTS: u32 = 4u;
// Whether any input is given (gpu::Specialization): without, loading them is compiled out.
override INPUTS: bool;

// Texture j: where its texels start in `input_texels`, its size and its values per texel (1 or 3; 0: not given).
struct InputTexture {
    at: u32,
    width: u32,
    height: u32,
    comps: u32,
}

@group(0) @binding(16) var<storage, read> input_textures: array<InputTexture>;
@group(0) @binding(17) var<storage, read> input_texels: array<f32>;
var<private> inputs: array<vec3<f32>, MAX_MODEL_INPUTS>;
var<private> inputs_given: u32;

// Input j of the current element (unused components 0).
fn input(j: u32) -> vec3<f32> {
    return inputs[j];
}

fn input_given(j: u32) -> bool {
    return ((inputs_given >> j) & 1u) != 0u;
}

// Every given input at texel (i, j) of its texture.
fn load_texels(uv: vec2<f32>, element: u32, by_uv: bool) {
    inputs_given = 0u;
    if !INPUTS {
        return;
    }
    for (var k = 0u; k < MAX_MODEL_INPUTS; k++) {
        let t = input_textures[k];
        inputs[k] = vec3<f32>(0.0);
        if t.comps == 0u {
            continue;
        }
        var texel = element;
        if by_uv {
            let i = min(u32(fract(uv.x) * f32(t.width)), t.width - 1u);
            let j = min(u32(fract(uv.y) * f32(t.height)), t.height - 1u);
            texel = j * t.width + i;
        }
        for (var c = 0u; c < min(t.comps, 3u); c++) {
            inputs[k][c] = input_texels[t.at + texel * t.comps + c];
        }
        inputs_given |= 1u << k;
    }
}

// The per-element queries: element i's inputs.
fn load_element_inputs(i: u32) {
    load_texels(vec2<f32>(0.0), i, false);
}

// The renderer: the inputs at a surface point's uv.
fn load_texture_inputs(uv: vec2<f32>) {
    load_texels(uv, 0u, true);
}
