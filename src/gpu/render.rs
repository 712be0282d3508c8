//! The renderer on the device: the scene's parameters and lights, meshes rasterized into visibility targets, and a
//! batch of stacks rendered in one dispatch (render.wgsl, env.wgsl).

use super::device::{
    buffer, dispatch, finish, gpu, group, group_of, init, scoped, Gpu, Res, Specialization, DEPTH, STORAGE, VISIBILITY,
};
use super::dispatch::{batched, cached_kernel, fits_the_mixture, input_buffers};
use super::{bytes, half, Kernel};
use crate::error::{value_error, Result};
use crate::models::Args;
use crate::render::Texture;
use crate::stack::Stack;

/// A light as scene.wgsl's `incident` reads it: two rows, (kind: 0 directional, 1 point; its direction or position)
/// and (its irradiance or intensity, 0).
pub fn light_rows(light: &crate::render::Light) -> [f32; 8] {
    use crate::render::Light;
    match *light {
        Light::Directional { direction: d, irradiance: e } => [0.0, d.x, d.y, d.z, e[0], e[1], e[2], 0.0],
        Light::Point { position: p, intensity: i } => [1.0, p.x, p.y, p.z, i[0], i[1], i[2], 0.0],
    }
    .map(|x| x as f32)
}

/// A scene for the GPU renderer: the image size, the shape (0 sphere, 1 plane, 2 the mesh), the mesh's arrays
/// (Mesh::gpu_arrays), the perspective camera's pinhole and its forward, right and up vectors (scaled as in
/// scene.wgsl; None: orthographic), and each light's rows (`light_rows`).
pub struct Scene {
    pub width: usize,
    pub height: usize,
    pub shape: u32,
    pub mesh: Option<(Vec<f32>, Vec<u32>)>,
    pub camera: Option<[[f32; 3]; 4]>,
    pub lights: Vec<[f32; 8]>,
    /// An environment light: EnvParams' words, the RGB radiance and the sampling distributions (Environment::gpu_data).
    pub env: Option<([u32; 8], Vec<f32>, Vec<f32>)>,
}

/// The scene's uniform parameters (RenderParams in scene.wgsl) for a dispatch rendering `stacks` images, and the
/// light rows, on the device.
pub(crate) fn scene_buffers(gpu: &Gpu, scene: &Scene, stacks: usize) -> (wgpu::Buffer, wgpu::Buffer) {
    let mut words = [0u32; 24];
    words[..6].copy_from_slice(&[
        scene.width as u32,
        scene.height as u32,
        scene.shape,
        scene.camera.is_some() as u32,
        scene.lights.len() as u32,
        stacks as u32,
    ]);
    for (r, v) in scene.camera.unwrap_or_default().iter().enumerate() {
        for (c, x) in v.iter().enumerate() {
            words[8 + 4 * r + c] = x.to_bits();
        }
    }
    let rows: Vec<f32> = if scene.lights.is_empty() { vec![0.0; 8] } else { scene.lights.concat() };
    (
        init(gpu, "render params", bytemuck::cast_slice(&words), wgpu::BufferUsages::UNIFORM),
        init(gpu, "lights", bytemuck::cast_slice(&rows), wgpu::BufferUsages::STORAGE),
    )
}

/// A visibility target of `size` texels (and a depth buffer with `depth`), cleared, and the mesh rasterized into it
/// by `pipeline` with the mesh's bind group (and the scene's, for the camera).
pub(crate) fn rasterize(
    gpu: &Gpu,
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::RenderPipeline,
    size: [usize; 2],
    mesh: [&wgpu::Buffer; 2],
    triangles: usize,
    scene: Option<&wgpu::Buffer>,
) -> wgpu::TextureView {
    let texture = |format, usage| {
        gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("visibility"),
            size: wgpu::Extent3d { width: size[0] as u32, height: size[1] as u32, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let target = texture(VISIBILITY, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING);
    let view = target.create_view(&Default::default());
    let depth = scene.map(|_| texture(DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT).create_view(&Default::default()));
    let bind = |g: u32, resources: &[(u32, Res)]| group_of(gpu, &pipeline.get_bind_group_layout(g), resources);
    let groups = [
        bind(0, &[]),
        scene.map_or_else(|| bind(1, &[]), |rp| bind(1, &[(0, Res::Buffer(rp))])),
        bind(2, &[(0, Res::Buffer(mesh[0])), (1, Res::Buffer(mesh[1]))]),
    ];
    let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("rasterize"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: &view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT), store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: depth.as_ref().map(|view| wgpu::RenderPassDepthStencilAttachment {
            view,
            depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_pipeline(pipeline);
    for (g, b) in groups.iter().enumerate() {
        pass.set_bind_group(g as u32, b, &[]);
    }
    pass.draw(0..3 * triangles as u32, 0..1);
    drop(pass);
    view
}

/// Renders each stack under the scene's lights (and environment), the model's per-element inputs as textures over
/// the surface's uv (catalogue order, or None; shared by the stacks): (stacks, height, width, 3) float32 radiance.
/// One dispatch renders every stack (`batched`), or as many as the adapter's storage-buffer limit holds.
pub fn render(
    model: &str,
    stacks: &[Stack],
    args: &Args,
    scene: &Scene,
    textures: &[Option<Texture>],
) -> Result<Vec<f32>> {
    let gpu = gpu()?;
    let image = 12 * scene.width * scene.height;
    let what = format!(
        "rendering {} image(s) of {} x {} with {model} ({} each)",
        stacks.len(),
        scene.width,
        scene.height,
        bytes(image)
    );
    let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
    if image > limit {
        return Err(gpu.failure(
            &what,
            &format!("an image needs {}, over the adapter's storage-buffer limit of {}", bytes(image), bytes(limit)),
        ));
    }
    scoped(&gpu, &what, || render_scoped(&gpu, model, stacks, args, scene, textures))
}

pub(crate) fn render_scoped(
    gpu: &Gpu,
    model: &str,
    stacks: &[Stack],
    args: &Args,
    scene: &Scene,
    textures: &[Option<Texture>],
) -> Result<Vec<f32>> {
    let kernel = scene.mesh.is_some() as usize + 2 * scene.env.is_some() as usize;
    if scene.env.is_some() {
        stacks.iter().try_for_each(fits_the_mixture)?;
    }
    let ups = stacks.iter().map(|s| cached_kernel(gpu, model, s, args)).collect::<Result<Vec<_>>>()?;
    if ups.iter().any(|u| u.kernel.channels != 3) {
        return value_error("render takes RGB stacks (3 channels)");
    }
    let env = scene.env.as_ref().map(|(words, rgb, dists)| {
        let params = init(gpu, "env params", bytemuck::cast_slice(words), wgpu::BufferUsages::UNIFORM);
        [
            params,
            init(gpu, "env", bytemuck::cast_slice(rgb), STORAGE),
            init(gpu, "env dists", bytemuck::cast_slice(dists), STORAGE),
        ]
    });
    let mesh = scene.mesh.as_ref().map(|(rows, tris)| {
        [
            init(gpu, "vertices", bytemuck::cast_slice(rows), STORAGE),
            init(gpu, "triangles", bytemuck::cast_slice(tris), STORAGE),
        ]
    });
    let inputs = input_buffers(gpu, textures);
    // Per stack, its image and its scratch (3 channels each) and its arrays must fit the storage-buffer limit.
    let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
    let image_bytes = 12 * scene.width * scene.height;
    let array_bytes = ups.iter().flat_map(|u| u.kernel.arrays.iter().map(|(a, _)| 4 * a.len())).max().unwrap_or(0);
    let per_dispatch = (limit / image_bytes.max(array_bytes).max(1)).max(1);
    // Stacks whose kernels run another model's shader (a single boundary under `tabulated` is microfacet's) render
    // in dispatches of their own; each image goes back to its stack's place.
    let mut image = vec![0f32; stacks.len() * image_bytes / 4];
    let mut shaders: Vec<&str> = ups.iter().map(|u| u.kernel.shader).collect();
    shaders.sort_unstable();
    shaders.dedup();
    for shader in shaders {
        let members: Vec<usize> = (0..ups.len()).filter(|&s| ups[s].kernel.shader == shader).collect();
        let spec = Specialization {
            fitted: members.iter().any(|&s| ups[s].kernel.fit.is_some()),
            inputs: textures.iter().any(Option::is_some),
        };
        let pipeline = gpu.render_pipeline(half(shader)?.0, kernel, spec);
        for chunk in members.chunks(per_dispatch) {
            let kernels: Vec<&Kernel> = chunk.iter().map(|&s| &ups[s].kernel).collect();
            let images = render_batch(gpu, pipeline, &kernels, scene, mesh.as_ref(), env.as_ref(), &inputs)?;
            for (&s, one) in chunk.iter().zip(images.chunks_exact(image_bytes / 4)) {
                image[s * image_bytes / 4..][..image_bytes / 4].copy_from_slice(one);
            }
        }
    }
    Ok(image)
}

/// One dispatch of the render `pipeline` over every pixel of each kernel's stack (a mesh rasterized once through the
/// camera first, its surface read back by each pixel): their images, one after the other.
pub(crate) fn render_batch(
    gpu: &Gpu,
    pipeline: &wgpu::ComputePipeline,
    kernels: &[&Kernel],
    scene: &Scene,
    mesh: Option<&[wgpu::Buffer; 2]>,
    env: Option<&[wgpu::Buffer; 3]>,
    inputs: &[wgpu::Buffer; 2],
) -> Result<Vec<f32>> {
    let threads = kernels.len() * scene.width * scene.height;
    let (render_params, lights) = scene_buffers(gpu, scene, kernels.len());
    let (words, buffers) = batched(gpu, kernels);
    let params = init(gpu, "params", bytemuck::cast_slice(&words), STORAGE);
    let size = (4 * 3 * threads) as u64;
    let scratch = buffer(gpu, "f", size, STORAGE);
    let image = buffer(gpu, "image", size, STORAGE | wgpu::BufferUsages::COPY_SRC);
    let read = buffer(gpu, "readback", size, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    // Group 0 as the render entry points use it: the parameters, the model's arrays, `out` (not `pairs`) and the fit.
    let model_buffers = buffers.resources(&params, None, &scratch, inputs);
    let scene_group = [(0, Res::Buffer(&render_params)), (1, Res::Buffer(&lights)), (2, Res::Buffer(&image))];
    let mut groups = vec![group(gpu, pipeline, 0, &model_buffers), group(gpu, pipeline, 1, &scene_group)];
    if let Some([vertices, triangles]) = mesh {
        let triangle_count = scene.mesh.as_ref().map_or(0, |(_, t)| t.len() / 3);
        let size = [scene.width, scene.height];
        let raster = &gpu.raster[1];
        let seen =
            rasterize(gpu, &mut encoder, raster, size, [vertices, triangles], triangle_count, Some(&render_params));
        let resources = [(0, Res::Buffer(vertices)), (1, Res::Buffer(triangles)), (2, Res::View(&seen))];
        groups.push(group(gpu, pipeline, 2, &resources));
    }
    if let Some(buffers) = env {
        if mesh.is_none() {
            // Groups are numbered: without a mesh, an empty group 2 keeps the environment at 3.
            groups.push(group(gpu, pipeline, 2, &[]));
        }
        let resources: Vec<(u32, Res)> = buffers.iter().enumerate().map(|(b, x)| (b as u32, Res::Buffer(x))).collect();
        groups.push(group(gpu, pipeline, 3, &resources));
    }
    dispatch(&mut encoder, pipeline, &groups.iter().collect::<Vec<_>>(), threads);
    encoder.copy_buffer_to_buffer(&image, 0, &read, 0, size);
    gpu.count_dispatch();
    finish(gpu, encoder, &read)
}
