// model="tabulated" on the GPU (src/models/tabulated.rs): the top interface's own reflection, exact, plus the
// trilinear interpolation of the adding-doubling table (tables/adding_doubling.rs: f less the top's reflection at
// NODES² zenith nodes x = √(1 − cos θ) × N_PHI azimuths y = sin(φ/2) between the travel directions, each reciprocal
// pair once). Composed after optics.wgsl and sample.wgsl.

const NODES: u32 = 65u;  // adding_doubling::NODES
const N_PHI: u32 = 33u;  // adding_doubling::N_PHI

struct Params {
    n: u32,
    channels: u32,
    g2: u32,
    has_top: u32,       // the top is rough (its reflection is part of f); 0: smooth, a Dirac lobe
    top: Microfacet,
    lobes: u32,         // the inner rough boundaries' lobes (sampling)
    pad0: u32,
    values_base: u32,   // where the stack's values start in `values`: the top's relative IOR per channel, the
                        // clear slab's depth below a smooth top per channel, then
    lobes_at: u32,      // (from values_base) the inner lobes, 6 values each (Microfacet), and
    albedo_at: u32,     // (from values_base) the albedo below the top per zenith node (NODES values)
    table_base: u32,    // where the stack's table starts in `table`
}

// Every stack's parameters (one for per-element queries; one per stack in a batched render, gpu::batched) and, in
// `params`, the current thread's.
@group(0) @binding(0) var<storage, read> stack_params: array<Params>;
var<private> params: Params;
@group(0) @binding(1) var<storage, read> values: array<f32>;
// [pair(i, o)][φ node][channel]
@group(0) @binding(2) var<storage, read> table: array<f32>;
@group(0) @binding(3) var<storage, read> pairs: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

fn eta(ch: u32) -> f32 {
    return values[params.values_base + ch];
}

// The clear slab's optical depth below a smooth top, channel ch (adding_doubling::clear_depth).
fn depth(ch: u32) -> f32 {
    return values[params.values_base + params.channels + ch];
}

// tabulated::entering: what of the light at zenith cosine z crosses a smooth top of relative IOR eta and the clear
// slab of optical depth d below it, T(z) e^(−d / cos θt); 1 for a top less dense than the outside.
fn entering(z: f32, eta: f32, d: f32) -> f32 {
    if eta < 1.0 {
        return 1.0;
    }
    let cos_t = sqrt(max((z * z + eta * eta - 1.0) / (eta * eta), 1e-12));
    return fresnel_dielectric_transmittance(z, eta) * exp(-d / cos_t);
}

// adding_doubling::pair: where the records of the zenith nodes (i, o) start, i and o in either order.
fn pair(i: u32, o: u32) -> u32 {
    let lo = min(i, o);
    let hi = max(i, o);
    return hi * (hi + 1u) / 2u + lo;
}

// tabulated::zenith: the table coordinate √(1 − cos θ).
fn zenith(z: f32) -> f32 {
    return sqrt(max(1.0 - z, 0.0));
}

// f(wi, wo) of every channel into out[base..]: the top's reflection plus the interpolated table (Prepared::eval_columns).
fn eval_pair(wi: vec3<f32>, wo: vec3<f32>, base: u32) {
    let above = wi.z > 0.0 && wo.z > 0.0;
    var geo = vec2<f32>(0.0);
    if above && params.has_top != 0u {
        geo = reflection_geometry(params.top, params.g2, wi, wo);
    }
    // The azimuth between the travel directions: y = sin(φ/2) = √((1 − cos φ)/2), cos φ = −cos(φi − φo).
    let d = sqrt((wi.x * wi.x + wi.y * wi.y) * (wo.x * wo.x + wo.y * wo.y));
    var cos_phi = 1.0;
    if d > 0.0 {
        cos_phi = -(wi.x * wo.x + wi.y * wo.y) / d;
    }
    let ni = table_node(zenith(wi.z), NODES);
    let no = table_node(zenith(wo.z), NODES);
    let np = table_node(sqrt(max(0.5 * (1.0 - cos_phi), 0.0)), N_PHI);
    let ch = params.channels;
    for (var c = 0u; c < ch; c++) {
        var f = 0.0;
        if above {
            for (var di = 0u; di < 2u; di++) {
                for (var dj = 0u; dj < 2u; dj++) {
                    let w = select(1.0 - ni.f, ni.f, di == 1u) * select(1.0 - no.f, no.f, dj == 1u);
                    let k = params.table_base + (pair(u32(ni.i) + di, u32(no.i) + dj) * N_PHI + u32(np.i)) * ch + c;
                    f += w * ((1.0 - np.f) * table[k] + np.f * table[k + ch]);
                }
            }
            // Below a smooth top, the table holds f / (Āi Āo): what enters through the top and its clear slab.
            if params.has_top == 0u {
                f *= entering(wi.z, eta(c), depth(c)) * entering(wo.z, eta(c), depth(c));
            }
        }
        out[base + c] = geo.x * fresnel_dielectric(geo.y, eta(c)) + f;
    }
}

// Prepared::proposals: the top's visible normals (weighted by its Fresnel reflectance) and the inner rough lobes
// sharing the albedo below the top (interpolated at wo's zenith node), or the cosine; the defensive share.
fn proposals(wo: vec3<f32>) {
    clear_mixture();
    let node = table_node(zenith(wo.z), NODES);
    let a = params.values_base + params.albedo_at + u32(node.i);
    let below = (1.0 - node.f) * values[a] + node.f * values[a + 1u];
    var slot = 0u;
    if params.has_top != 0u {
        add_term(slot, REFLECTION, fresnel_dielectric(wo.z, eta(0u)), params.top);
        slot += 1u;
    }
    let share = below / f32(max(params.lobes, 1u));
    for (var l = 0u; l < params.lobes; l++) {
        let at = params.values_base + params.lobes_at + 6u * l;
        let mf = Microfacet(u32(values[at]), u32(values[at + 1u]), values[at + 2u], values[at + 3u], values[at + 4u], values[at + 5u]);
        add_term(slot, REFLECTION, share, mf);
        slot += 1u;
    }
    if params.lobes == 0u {
        add_term(slot, COSINE, below, cosine_lobe());
    }
    add_defensive_share();
}

// Prepared::specular: a smooth top's mirror reflection of channel ch.
fn specular(wo: vec3<f32>, ch: u32) -> f32 {
    if wo.z <= 0.0 || params.has_top != 0u {
        return 0.0;
    }
    return fresnel_dielectric(wo.z, eta(ch));
}
