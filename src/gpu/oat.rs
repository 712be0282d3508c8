//! Oat 2006's gooey layers on the GPU (shaders/oat.wgsl, mirroring render/oat.rs): per material, one dispatch that
//! lights the texture-space light map over the shape's uv chart (variant "full"), then one that shades every pixel;
//! all materials in one submission. The sphere and the plane, under directional and point lights, in float32.

use super::{bind, buffer, finish, gpu, init, record, scene_buffers, scoped, Gpu, Scene, OPTICS, SCENE};
use crate::error::{value_error, Result};
use crate::render::oat::{Material, Prepared, Variant};
use crate::render::Texture;
use std::sync::Arc;

/// The shader: the primitives, the scene, then Oat's kernels.
pub fn compose() -> String {
    format!("{OPTICS}\n{SCENE}\n{}", include_str!("shaders/oat.wgsl"))
}

/// The material's parameters in the layout of `OatParams`.
fn words(m: &Material) -> [u32; 8] {
    let variant = match m.variant {
        Variant::Full => 0,
        Variant::NormalFiltered => 1,
        Variant::VertexNormal => 2,
    };
    let border = matches!(m.border, crate::render::Border::Wrap) as u32;
    let texel = m.texel.map(|x| (x as f32).to_bits());
    [variant, m.shadowing as u32, border, m.inner.len() as u32, texel[0], texel[1], 0, 0]
}

/// The material's textures in one float32 array and their (offset, width, height, comps) rows, in oat.wgsl's order:
/// outer albedo, opacity and normal, the light map (the normal map's size for "full", else 1 x 1, unused), then per
/// inner layer its albedo, opacity (0 comps for the deepest) and depth.
fn pack(m: &Material) -> Packed {
    let (mut rows, mut data) = (Vec::new(), Vec::new());
    let mut push = |t: Option<&Texture>, size: [usize; 3]| {
        rows.push([data.len() as u32, size[0] as u32, size[1] as u32, size[2] as u32]);
        match t {
            Some(t) => data.extend(t.data.iter().map(|&x| x as f32)),
            None => data.extend(std::iter::repeat_n(0f32, size.iter().product())),
        }
    };
    let size = |t: &Texture| [t.width, t.height, t.comps];
    for t in [&m.outer_albedo, &m.outer_opacity, &m.outer_normal] {
        push(Some(t), size(t));
    }
    let n = &m.outer_normal;
    push(None, if m.variant == Variant::Full { [n.width, n.height, 3] } else { [1, 1, 3] });
    for layer in &m.inner {
        push(Some(&layer.albedo), size(&layer.albedo));
        match &layer.opacity {
            Some(t) => push(Some(t), size(t)),
            None => push(None, [1, 1, 0]),
        }
        push(Some(&layer.depth), size(&layer.depth));
    }
    (rows, data)
}

/// Renders each material: (materials, height, width, 3) float32 radiance. The light map is computed here, on the
/// device, whatever `Prepared` holds.
pub fn render(materials: &[Arc<Prepared>], scene: &Scene) -> Result<Vec<f32>> {
    let gpu = gpu()?;
    let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
    let packed: Vec<_> = materials.iter().map(|m| pack(&m.material)).collect();
    if let Some(bytes) = packed.iter().map(|(_, data)| 4 * data.len()).find(|&b| b > limit) {
        return value_error(format!(
            "an Oat material's textures take {} MiB on the GPU, over the adapter's storage-buffer limit of {} MiB: use \
             smaller textures or device='cpu'",
            bytes >> 20,
            limit >> 20
        ));
    }
    scoped(gpu, || render_scoped(gpu, materials, &packed, scene))
}

type Packed = (Vec<[u32; 4]>, Vec<f32>);

fn render_scoped(gpu: &'static Gpu, materials: &[Arc<Prepared>], packed: &[Packed], scene: &Scene) -> Result<Vec<f32>> {
    let [lighting, shading] = &gpu.oat;
    let pixels = scene.width * scene.height;
    let (render_params, lights) = scene_buffers(gpu, scene);
    let size = (4 * 3 * pixels) as u64;
    let usage = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
    let read = buffer(gpu, "readback", size * materials.len() as u64, usage);
    let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    let mut keep = Vec::new();
    for (s, (prepared, (rows, data))) in materials.iter().zip(packed).enumerate() {
        let m = &prepared.material;
        let params = init(gpu, "oat params", bytemuck::cast_slice(&words(m)), wgpu::BufferUsages::UNIFORM);
        let textures = init(gpu, "textures", bytemuck::cast_slice(rows), wgpu::BufferUsages::STORAGE);
        let texels = init(gpu, "texels", bytemuck::cast_slice(data), wgpu::BufferUsages::STORAGE);
        let image = buffer(gpu, "image", size, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
        let material = [(0, &params), (1, &textures), (2, &texels)];
        if m.variant == Variant::Full {
            let g0 = bind(gpu, lighting, 0, &material[1..]); // the light map does not read the parameters
            let g1 = bind(gpu, lighting, 1, &[(0, &render_params), (1, &lights)]);
            record(&mut encoder, lighting, [&g0, &g1], m.outer_normal.width * m.outer_normal.height);
        }
        let g0 = bind(gpu, shading, 0, &material);
        let g1 = bind(gpu, shading, 1, &[(0, &render_params), (1, &lights), (2, &image)]);
        record(&mut encoder, shading, [&g0, &g1], pixels);
        encoder.copy_buffer_to_buffer(&image, 0, &read, s as u64 * size, size);
        keep.push((params, textures, texels, image));
    }
    finish(gpu, encoder, &read)
}
