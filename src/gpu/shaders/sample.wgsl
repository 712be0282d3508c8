// Importance sampling on the GPU (src/models/common/mixture.rs): a one-sample mixture of the lobes a model proposes for the
// viewing direction, reflection lobes through their visible normals and diffuse terms by the cosine. Each model's
// shader builds the mixture (its `proposals(wo)` fills `lobes`); the renderer samples it. Composed after optics.wgsl.

const MAX_LOBES: u32 = 16u;
const COSINE: u32 = 0u;
const REFLECTION: u32 = 1u;
// mixture::DEFENSIVE: the cosine share of a layered model's mixture.
const DEFENSIVE: f32 = 0.05;

// mixture::weight_factor: what turns f at a sampled wi into the weight f cos θi / pdf; 0 for a lost sample.
fn weight_factor(wi: vec3<f32>, pdf: f32) -> f32 {
    return select(0.0, wi.z / pdf, pdf > 0.0);
}

struct Lobe {
    kind: u32,
    weight: f32,
    mf: Microfacet,
}

// The proposals for the current viewing direction with their (unnormalised) weights, in the order of the CPU's
// (so that the same u picks the same lobe), in private memory (a kernel builds one mixture at a time, and copying it
// by value costs the shader compilers dearly).
var<private> lobes: array<Lobe, MAX_LOBES>;
var<private> lobe_count: u32;

fn clear_mixture() {
    lobe_count = 0u;
}

// Adds `weight` to the term in `slot` (a model's terms have fixed slots; a model whose energies add up over channels
// adds each channel's share to the same slots), creating it if new. The host keeps stacks within MAX_LOBES.
fn add_term(slot: u32, kind: u32, weight: f32, mf: Microfacet) {
    if slot >= MAX_LOBES {
        return;
    }
    if slot >= lobe_count {
        lobes[slot] = Lobe(kind, 0.0, mf);
        lobe_count = slot + 1u;
    }
    lobes[slot].weight += weight;
}

// Keeps the terms with energy, in order (mixture::defensive_mixture's filter).
fn keep_terms_with_energy() {
    var kept = 0u;
    for (var k = 0u; k < lobe_count; k++) {
        if lobes[k].weight > 0.0 {
            lobes[kept] = lobes[k];
            kept += 1u;
        }
    }
    lobe_count = kept;
}

fn cosine_lobe() -> Microfacet {
    return Microfacet(0u, 1u, 1.0, 1.0, 1.0, 0.0);
}

fn total_weight() -> f32 {
    var total = 0.0;
    for (var k = 0u; k < lobe_count; k++) {
        total += lobes[k].weight;
    }
    return total;
}

// mixture::defensive_mixture: the terms with energy, then the DEFENSIVE cosine share (none when nothing has energy).
fn add_defensive_share() {
    keep_terms_with_energy();
    let total = total_weight();
    if total > 0.0 {
        add_term(lobe_count, COSINE, DEFENSIVE * total / (1.0 - DEFENSIVE), cosine_lobe());
    }
}

// mixture::lobe_pdf: D_wo(h) / (4 wo·h) for a reflection lobe, cos θi / π for the cosine.
fn lobe_pdf(lobe: Lobe, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    if lobe.kind == COSINE {
        return max(wi.z, 0.0) * FRAC_1_PI;
    }
    let h = normalize(wi + wo);
    let c = dot(wo, h);
    if c > 0.0 {
        return mf_pdf_visible(lobe.mf, wo, h) / (4.0 * c);
    }
    return 0.0;
}

// mixture::mixture_pdf: the mixture's pdf of wi for wo; 0 below the horizon.
fn mixture_pdf(wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    let total = total_weight();
    if wi.z <= 0.0 || wo.z <= 0.0 || total <= 0.0 {
        return 0.0;
    }
    var p = 0.0;
    for (var k = 0u; k < lobe_count; k++) {
        p += lobes[k].weight / total * lobe_pdf(lobes[k], wi, wo);
    }
    return p;
}

// mixture::sample_mixture: (wi, pdf) from three uniform numbers; pdf 0 when nothing can be sampled or wi is lost
// below the horizon.
fn sample_mixture(wo: vec3<f32>, u: vec3<f32>) -> vec4<f32> {
    let total = total_weight();
    if lobe_count == 0u || total <= 0.0 || wo.z <= 0.0 {
        return vec4<f32>(0.0, 0.0, 1.0, 0.0);
    }
    let u0 = clamp(u.x, 0.0, 1.0) * total;
    var chosen = lobe_count - 1u;
    var acc = 0.0;
    for (var k = 0u; k < lobe_count; k++) {
        acc += lobes[k].weight;
        if u0 < acc {
            chosen = k;
            break;
        }
    }
    var wi: vec3<f32>;
    if lobes[chosen].kind == COSINE {
        wi = cosine_hemisphere(u.y, u.z);
    } else {
        wi = reflect_about(wo, mf_sample_visible(lobes[chosen].mf, wo, u.y, u.z));
    }
    if !(wi.z > 0.0) {
        return vec4<f32>(wi, 0.0);
    }
    return vec4<f32>(wi, mixture_pdf(wi, wo));
}
