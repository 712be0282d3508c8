//! Oat 2006's gooey layers on the GPU (oat.wgsl, mirroring src/oat/mod.rs), under directional and point
//! lights, in float32; all materials in one submission. On the sphere and the plane, per material one dispatch
//! lights the texture-space light map over the shape's uv chart (variant "full") and one shades every pixel. On a
//! mesh (shaders/mesh.wgsl, raster.wgsl), a render pass rasterizes it through the camera into a visibility target
//! once; per material, a render pass with the uvs as positions rasterizes it in uv space, a dispatch lights the
//! covered texels, `dilate` dispatches dilate the islands and one stores the light map, before the shading
//! dispatch reads the surface back from the visibility target.

use super::{Material, Prepared, Technique};
use crate::error::{value_error, Result};
use crate::gpu::{
    buffer, bytes, compute_module, compute_pipeline, dispatch, finish, gpu, group, init, rasterize, scene_buffers,
    scoped, Gpu, Res, Scene, MESH, OPTICS, SCENE,
};
use crate::render::{Border, Texture};
use std::sync::Arc;

/// The shader: the primitives, the scene, the mesh, then Oat's kernels.
pub fn compose() -> String {
    format!("{OPTICS}\n{SCENE}\n{MESH}\n{}", include_str!("oat.wgsl"))
}

/// Oat's kernels, in the order of `pipelines`.
pub const KERNELS: [&str; 6] =
    ["light_map", "render_oat", "light_map_mesh", "dilate", "store_light_map", "render_oat_mesh"];

/// Oat's pipelines on `gpu` (in the order of KERNELS), compiled on the first render, as the models' are.
fn pipelines(gpu: &Gpu) -> &[wgpu::ComputePipeline] {
    gpu.oat.get_or_init(|| {
        let module = compute_module(&gpu.device, "oat", compose());
        KERNELS.iter().map(|entry| compute_pipeline(&gpu.device, &module, entry)).collect()
    })
}

/// The material's parameters in the layout of `OatParams`.
fn words(m: &Material) -> [u32; 8] {
    let technique = match m.technique {
        Technique::Full => 0,
        Technique::NormalFiltered => 1,
        Technique::VertexNormal => 2,
    };
    let border = matches!(m.border, Border::Wrap) as u32;
    let texel = m.texel.map(|x| (x as f32).to_bits());
    [technique, m.shadowing as u32, border, m.inner.len() as u32, texel[0], texel[1], 0, 0]
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
    push(None, if m.technique == Technique::Full { [n.width, n.height, 3] } else { [1, 1, 3] });
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
    let texels: usize = packed.iter().map(|(_, data)| 4 * data.len()).sum();
    let what = format!(
        "rendering {} Oat material(s) at {} x {} ({} of textures)",
        materials.len(),
        scene.width,
        scene.height,
        bytes(texels)
    );
    scoped(&gpu, &what, || render_scoped(&gpu, materials, &packed, scene))
}

type Packed = (Vec<[u32; 4]>, Vec<f32>);

fn render_scoped(gpu: &Gpu, materials: &[Arc<Prepared>], packed: &[Packed], scene: &Scene) -> Result<Vec<f32>> {
    let [light_map, render, light_map_mesh, dilate, store, render_mesh] = pipelines(gpu) else {
        unreachable!("one pipeline per kernel")
    };
    let pixels = scene.width * scene.height;
    let (render_params, lights) = scene_buffers(gpu, scene, 1);
    let size = (4 * 3 * pixels) as u64;
    let usage = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
    let read = buffer(gpu, "readback", size * materials.len() as u64, usage);
    let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    let mesh = scene.mesh.as_ref().map(|(rows, tris)| {
        let vertices = init(gpu, "vertices", bytemuck::cast_slice(rows), wgpu::BufferUsages::STORAGE);
        let triangles = init(gpu, "triangles", bytemuck::cast_slice(tris), wgpu::BufferUsages::STORAGE);
        (vertices, triangles, tris.len() / 3)
    });
    let seen = mesh.as_ref().map(|(v, t, n)| {
        rasterize(gpu, &mut encoder, &gpu.raster[1], [scene.width, scene.height], [v, t], *n, Some(&render_params))
    });
    let (mut buffers, mut views) = (Vec::new(), Vec::new());
    for (s, (prepared, (rows, data))) in materials.iter().zip(packed).enumerate() {
        let m = &prepared.material;
        let params = init(gpu, "oat params", bytemuck::cast_slice(&words(m)), wgpu::BufferUsages::UNIFORM);
        let textures = init(gpu, "textures", bytemuck::cast_slice(rows), wgpu::BufferUsages::STORAGE);
        let texels = init(gpu, "texels", bytemuck::cast_slice(data), wgpu::BufferUsages::STORAGE);
        let image = buffer(gpu, "image", size, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
        let (op, tex, texel) = ((0, Res::Buffer(&params)), (1, Res::Buffer(&textures)), (2, Res::Buffer(&texels)));
        let scene_group = |p: &wgpu::ComputePipeline, with_image: bool| {
            let mut r = vec![(0, Res::Buffer(&render_params)), (1, Res::Buffer(&lights))];
            if with_image {
                r.push((2, Res::Buffer(&image)));
            }
            group(gpu, p, 1, &r)
        };
        let texels_n = m.outer_normal.width * m.outer_normal.height;
        match (&mesh, &seen) {
            (None, _) => {
                if m.technique == Technique::Full {
                    let p = light_map;
                    let g = [group(gpu, p, 0, &[tex, texel]), scene_group(p, false)];
                    dispatch(&mut encoder, p, &[&g[0], &g[1]], texels_n);
                }
                let p = render;
                let g = [group(gpu, p, 0, &[op, tex, texel]), scene_group(p, true)];
                dispatch(&mut encoder, p, &[&g[0], &g[1]], pixels);
            }
            (Some((vertices, triangles, n)), Some(seen)) => {
                let (v, t) = ((0, Res::Buffer(vertices)), (1, Res::Buffer(triangles)));
                if m.technique == Technique::Full {
                    let size = [m.outer_normal.width, m.outer_normal.height];
                    let uv = rasterize(gpu, &mut encoder, &gpu.raster[0], size, [vertices, triangles], *n, None);
                    let state =
                        [0, 1].map(|_| buffer(gpu, "dilation", 16 * texels_n as u64, wgpu::BufferUsages::STORAGE));
                    let p = light_map_mesh;
                    let g = [
                        group(gpu, p, 0, &[tex, texel]),
                        scene_group(p, false),
                        group(
                            gpu,
                            p,
                            2,
                            &[
                                (0, Res::Buffer(vertices)),
                                (1, Res::Buffer(triangles)),
                                (2, Res::View(&uv)),
                                (4, Res::Buffer(&state[0])),
                            ],
                        ),
                    ];
                    dispatch(&mut encoder, p, &[&g[0], &g[1], &g[2]], texels_n);
                    let p = dilate;
                    for pass in 0..m.dilate {
                        let (from, to) = (&state[pass % 2], &state[(pass + 1) % 2]);
                        let g = [
                            group(gpu, p, 0, &[(1, Res::Buffer(&textures))]),
                            group(gpu, p, 1, &[]),
                            group(gpu, p, 2, &[(3, Res::Buffer(from)), (4, Res::Buffer(to))]),
                        ];
                        dispatch(&mut encoder, p, &[&g[0], &g[1], &g[2]], texels_n);
                    }
                    let p = store;
                    let g = [
                        group(gpu, p, 0, &[(1, Res::Buffer(&textures)), (2, Res::Buffer(&texels))]),
                        group(gpu, p, 1, &[]),
                        group(gpu, p, 2, &[(3, Res::Buffer(&state[m.dilate % 2]))]),
                    ];
                    dispatch(&mut encoder, p, &[&g[0], &g[1], &g[2]], texels_n);
                    views.push(uv);
                    buffers.extend(state);
                }
                let p = render_mesh;
                let g = [
                    group(gpu, p, 0, &[op, tex, texel]),
                    scene_group(p, true),
                    group(gpu, p, 2, &[v, t, (2, Res::View(seen))]),
                ];
                dispatch(&mut encoder, p, &[&g[0], &g[1], &g[2]], pixels);
            }
            _ => unreachable!("a mesh is rasterized through the camera"),
        }
        encoder.copy_buffer_to_buffer(&image, 0, &read, s as u64 * size, size);
        buffers.extend([params, textures, texels, image]);
    }
    gpu.count_dispatch();
    finish(gpu, encoder, &read) // the buffers and views live until the work is done
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_shader_is_valid_wgsl() {
        crate::gpu::tests::validate("oat", &super::compose());
    }
}
