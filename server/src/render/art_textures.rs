//! GPU copies of the art maps: each tonal art map as a 2D array texture (one layer per tone
//! level, its own hand-drawn mip chain), each silhouette art map as an RGBA texture.

use super::artmaps::{Sam, Tam, TamStyle, generate_sams, generate_tam};

/// Side of the generated TAM tone images in pixels.
pub const TAM_SIZE: u32 = 256;
/// Tone levels of the generated TAMs.
pub const TAM_LEVELS: usize = 6;
/// Size of the generated SAMs: 256 px along the contour, 32 px of support.
pub const SAM_SIZE: (u32, u32) = (256, 32);

/// One uploaded tonal art map.
pub struct GpuTam {
    pub view: wgpu::TextureView,
    pub levels: u32,
    pub size: u32,
}

/// The art maps a renderer can use, addressed by index from the style.
pub struct ArtTextures {
    pub tams: Vec<GpuTam>,
    /// Every TAM in one 2D array texture, TAM `i`'s tone level `l` at layer `i · levels + l`,
    /// so a pass can pick the TAM per pixel (hatch pattern per label, thesis Table 9.1).
    pub all_tams: wgpu::TextureView,
    pub sams: Vec<wgpu::TextureView>,
    pub tam_sampler: wgpu::Sampler,
    pub sam_sampler: wgpu::Sampler,
}

/// The default TAMs, in index order: lines, cross-hatching, scribbles, stipples.
pub const DEFAULT_TAM_STYLES: [TamStyle; 4] =
    [TamStyle::Lines, TamStyle::CrossHatch, TamStyle::Scribble, TamStyle::Stipple];

/// Uploads `tams` (same size, levels and mips) into one array texture, tone levels in order.
fn upload_tams(device: &wgpu::Device, queue: &wgpu::Queue, tams: &[&Tam]) -> GpuTam {
    let tam = tams[0];
    let mips = tam.levels[0].len() as u32;
    let layers = tams.iter().map(|t| t.levels.len() as u32).sum();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("tam"),
        size: wgpu::Extent3d { width: tam.size, height: tam.size, depth_or_array_layers: layers },
        mip_level_count: mips,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (layer, level) in tams.iter().flat_map(|t| &t.levels).enumerate() {
        for (mip, image) in level.iter().enumerate() {
            let (w, h) = image.dimensions();
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: mip as u32,
                    origin: wgpu::Origin3d { x: 0, y: 0, z: layer as u32 },
                    aspect: wgpu::TextureAspect::All,
                },
                image,
                wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w), rows_per_image: Some(h) },
                wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
            );
        }
    }
    let view = texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });
    GpuTam { view, levels: tam.levels.len() as u32, size: tam.size }
}

fn upload_sam(device: &wgpu::Device, queue: &wgpu::Queue, sam: &Sam) -> wgpu::TextureView {
    let (width, height) = sam.image.dimensions();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("sam"),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        &sam.image,
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * width), rows_per_image: Some(height) },
        wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
    );
    texture.create_view(&Default::default())
}

impl ArtTextures {
    /// Generates and uploads the default art maps: the four [`DEFAULT_TAM_STYLES`] and the
    /// generated SAMs (deterministic, so every renderer draws the same strokes).
    pub fn defaults(device: &wgpu::Device, queue: &wgpu::Queue) -> ArtTextures {
        let tams =
            DEFAULT_TAM_STYLES.iter().map(|style| generate_tam(*style, TAM_SIZE, TAM_LEVELS, 1)).collect::<Vec<_>>();
        let sams = generate_sams(SAM_SIZE.0, SAM_SIZE.1, 1);
        ArtTextures::new(device, queue, &tams, &sams)
    }

    /// Uploads the given art maps (every TAM of the same size, levels and mip count).
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, tams: &[Tam], sams: &[Sam]) -> ArtTextures {
        let sampler = |v| {
            device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("art map"),
                address_mode_u: wgpu::AddressMode::Repeat,
                address_mode_v: v,
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: wgpu::MipmapFilterMode::Linear,
                ..Default::default()
            })
        };
        ArtTextures {
            tams: tams.iter().map(|t| upload_tams(device, queue, &[t])).collect(),
            all_tams: upload_tams(device, queue, &tams.iter().collect::<Vec<_>>()).view,
            sams: sams.iter().map(|s| upload_sam(device, queue, s)).collect(),
            tam_sampler: sampler(wgpu::AddressMode::Repeat),
            sam_sampler: sampler(wgpu::AddressMode::ClampToEdge),
        }
    }
}
