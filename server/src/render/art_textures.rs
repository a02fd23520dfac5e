//! GPU copies of the art maps: each tonal art map as a 2D array texture (one layer per tone
//! level, its own hand-drawn mip chain), each silhouette art map as an RGBA texture. The CPU
//! copies are kept too, so that an art map can be replaced or added at run time (thesis
//! 8.2.5: art maps painted on the fly) and the array of every TAM rebuilt.

use super::RenderError;
use super::artmaps::{Sam, Tam, TamStyle, generate_sams, generate_tam};
use std::sync::Arc;

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
    /// Whether its strokes run in one direction ([`Tam::directional`]).
    pub directional: bool,
}

/// The most art maps of one kind a renderer holds (styles index them with 0..=255).
pub const MAX_ART_MAPS: usize = 32;

/// The two kinds of art maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ArtKind {
    /// Tonal art map (`Style::hatch_map`).
    Tam,
    /// Silhouette art map (`Style::silhouette_map`).
    Sam,
}

impl ArtKind {
    /// Both kinds.
    pub const ALL: [ArtKind; 2] = [ArtKind::Tam, ArtKind::Sam];

    /// Short name: `tam` or `sam` (API paths, file names).
    pub fn name(self) -> &'static str {
        match self {
            ArtKind::Tam => "tam",
            ArtKind::Sam => "sam",
        }
    }

    /// The kind named `tam` or `sam`.
    pub fn from_name(name: &str) -> Option<ArtKind> {
        ArtKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

impl std::fmt::Display for ArtKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ArtKind::Tam => "tonal art map",
            ArtKind::Sam => "silhouette art map",
        })
    }
}

/// One art map on the CPU.
#[derive(Debug, Clone)]
pub enum ArtMap {
    /// A tonal art map.
    Tam(Arc<Tam>),
    /// A silhouette art map.
    Sam(Arc<Sam>),
}

impl ArtMap {
    /// Its kind.
    pub fn kind(&self) -> ArtKind {
        match self {
            ArtMap::Tam(_) => ArtKind::Tam,
            ArtMap::Sam(_) => ArtKind::Sam,
        }
    }
}

/// The CPU copies of a renderer's art maps in index order (cheap to clone).
#[derive(Debug, Clone, Default)]
pub struct ArtMapSet {
    /// Tonal art maps, indexed by `Style::hatch_map`.
    pub tams: Vec<Arc<Tam>>,
    /// Silhouette art maps, indexed by `Style::silhouette_map`.
    pub sams: Vec<Arc<Sam>>,
}

impl ArtMapSet {
    /// How many maps of `kind` there are.
    pub fn count(&self, kind: ArtKind) -> usize {
        match kind {
            ArtKind::Tam => self.tams.len(),
            ArtKind::Sam => self.sams.len(),
        }
    }

    /// Map `index` of `kind`, if there is one.
    pub fn get(&self, kind: ArtKind, index: usize) -> Option<ArtMap> {
        match kind {
            ArtKind::Tam => self.tams.get(index).cloned().map(ArtMap::Tam),
            ArtKind::Sam => self.sams.get(index).cloned().map(ArtMap::Sam),
        }
    }
}

/// The art maps a renderer can use, addressed by index from the style.
pub struct ArtTextures {
    pub tams: Vec<GpuTam>,
    /// Every TAM in one 2D array texture, TAM `i`'s pair of tone levels `l − 1`, `l` at layer
    /// `i · (levels + 1) + l` ([`upload_tams`]), so a pass can pick the TAM per pixel (hatch
    /// pattern per label, thesis Table 9.1).
    pub all_tams: wgpu::TextureView,
    pub sams: Vec<wgpu::TextureView>,
    pub tam_sampler: wgpu::Sampler,
    pub sam_sampler: wgpu::Sampler,
    /// The CPU copies the textures were uploaded from.
    pub maps: ArtMapSet,
}

impl ArtTextures {
    /// Bit `i` set where TAM `i` is directional ([`GpuTam::directional`]; at most
    /// [`MAX_ART_MAPS`] = 32 TAMs).
    pub fn directional_tams(&self) -> u32 {
        self.tams.iter().enumerate().filter(|(_, t)| t.directional).fold(0, |mask, (i, _)| mask | 1 << i)
    }
}

/// The default TAMs, in index order: lines, cross-hatching, scribbles, stipples.
pub const DEFAULT_TAM_STYLES: [TamStyle; 4] =
    [TamStyle::Lines, TamStyle::CrossHatch, TamStyle::Scribble, TamStyle::Stipple];

/// Uploads `tams` (same size, levels and mips) into one array texture of tone-level pairs:
/// each TAM of `n` levels takes `n + 1` layers ([`tam_layers`]), layer `j` holding level
/// `j − 1` in red (paper for `j = 0`) and level `j` in green (the darkest level again for
/// `j = n`), so the compose pass blends the two levels that bracket a tone from one lookup
/// (`tam_ink` in `shaders/compose.wgsl`; lavapipe pays per texture lookup).
fn upload_tams(device: &wgpu::Device, queue: &wgpu::Queue, tams: &[&Tam]) -> GpuTam {
    let tam = tams[0];
    let mips = tam.levels[0].len() as u32;
    let layers = tams.iter().map(|t| tam_layers(t.levels.len()) as u32).sum();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("tam"),
        size: wgpu::Extent3d { width: tam.size, height: tam.size, depth_or_array_layers: layers },
        mip_level_count: mips,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rg8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let pairs = tams.iter().flat_map(|t| {
        let n = t.levels.len();
        (0..=n).map(move |j| (j.checked_sub(1).map(|lighter| &t.levels[lighter]), &t.levels[j.min(n - 1)]))
    });
    for (layer, (lighter, darker)) in pairs.enumerate() {
        for (mip, image) in darker.iter().enumerate() {
            let (w, h) = image.dimensions();
            let red = |i: usize| lighter.map_or(u8::MAX, |levels| levels[mip].as_raw()[i]);
            let texels: Vec<u8> = image.as_raw().iter().enumerate().flat_map(|(i, &g)| [red(i), g]).collect();
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: mip as u32,
                    origin: wgpu::Origin3d { x: 0, y: 0, z: layer as u32 },
                    aspect: wgpu::TextureAspect::All,
                },
                &texels,
                wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(2 * w), rows_per_image: Some(h) },
                wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
            );
        }
    }
    let view = texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });
    GpuTam { view, levels: tam.levels.len() as u32, size: tam.size, directional: tam.directional() }
}

/// The array layers a TAM of `levels` tone levels takes on the GPU: its `levels + 1` pairs of
/// adjacent levels (see [`upload_tams`]).
pub fn tam_layers(levels: usize) -> usize {
    levels + 1
}

/// The array texture of every TAM (see [`ArtTextures::all_tams`]).
fn upload_all_tams(device: &wgpu::Device, queue: &wgpu::Queue, tams: &[Arc<Tam>]) -> wgpu::TextureView {
    upload_tams(device, queue, &tams.iter().map(|t| &**t).collect::<Vec<_>>()).view
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
        let tams = DEFAULT_TAM_STYLES
            .iter()
            .map(|style| Arc::new(generate_tam(*style, TAM_SIZE, TAM_LEVELS, 1)))
            .collect::<Vec<_>>();
        let sams = generate_sams(SAM_SIZE.0, SAM_SIZE.1, 1).into_iter().map(Arc::new).collect();
        ArtTextures::new(device, queue, ArtMapSet { tams, sams })
    }

    /// Uploads the given art maps (every TAM of the same size, levels and mip count).
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, maps: ArtMapSet) -> ArtTextures {
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
            tams: maps.tams.iter().map(|t| upload_tams(device, queue, &[t])).collect(),
            all_tams: upload_all_tams(device, queue, &maps.tams),
            sams: maps.sams.iter().map(|s| upload_sam(device, queue, s)).collect(),
            tam_sampler: sampler(wgpu::AddressMode::Repeat),
            sam_sampler: sampler(wgpu::AddressMode::ClampToEdge),
            maps,
        }
    }

    /// Replaces art map `index` of the map's kind, or adds one when `index` is the count. A
    /// TAM must have the tone-image size, tone levels and mip count of the other TAMs (they
    /// share one array texture), a SAM fit the device's textures; the array of every TAM is
    /// rebuilt. Nothing changes when the map is refused.
    pub fn set(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        index: usize,
        map: ArtMap,
    ) -> Result<(), RenderError> {
        let kind = map.kind();
        let count = self.maps.count(kind);
        let refuse = |message: String| RenderError::ArtMap { kind, index, message };
        if index > count {
            return Err(refuse(format!("there are {count}: replace 0..{count} or add one as {count}")));
        }
        if index == count && count >= MAX_ART_MAPS {
            return Err(refuse(format!("a renderer holds at most {MAX_ART_MAPS}")));
        }
        match map {
            ArtMap::Tam(tam) => {
                // The shape to keep: any other TAM's (the only one may be replaced by any).
                let other = self.maps.tams.iter().enumerate().find(|(i, _)| *i != index).map(|(_, t)| t);
                if let Some(other) = other {
                    let shape = |t: &Tam| (t.size, t.levels.len(), t.levels.first().map_or(0, Vec::len));
                    let ((size, levels, mips), (want_size, want_levels, want_mips)) = (shape(&tam), shape(other));
                    if (size, levels, mips) != (want_size, want_levels, want_mips) {
                        return Err(refuse(format!(
                            "its tone images are {size}×{size} pixels with {levels} levels and {mips} mips; this renderer's TAMs are {want_size}×{want_size} with {want_levels} levels and {want_mips} mips (a PNG strip of {} × {want_size} pixels)",
                            want_size as usize * want_levels
                        )));
                    }
                }
                let layers = (count + usize::from(index == count)) * tam_layers(tam.levels.len());
                let max_layers = device.limits().max_texture_array_layers as usize;
                if layers > max_layers {
                    return Err(refuse(format!(
                        "all TAMs together would need {layers} texture layers; the device has {max_layers}"
                    )));
                }
                let gpu = upload_tams(device, queue, &[&tam]);
                if index == count {
                    self.tams.push(gpu);
                    self.maps.tams.push(tam);
                } else {
                    self.tams[index] = gpu;
                    self.maps.tams[index] = tam;
                }
                self.all_tams = upload_all_tams(device, queue, &self.maps.tams);
            }
            ArtMap::Sam(sam) => {
                let (width, height) = sam.image.dimensions();
                let max = device.limits().max_texture_dimension_2d;
                if width == 0 || height == 0 || width > max || height > max {
                    return Err(refuse(format!("it is {width}×{height} pixels; the device takes 1..={max} per side")));
                }
                let gpu = upload_sam(device, queue, &sam);
                if index == count {
                    self.sams.push(gpu);
                    self.maps.sams.push(sam);
                } else {
                    self.sams[index] = gpu;
                    self.maps.sams[index] = sam;
                }
            }
        }
        Ok(())
    }

    /// Removes art map `index` of `kind`, which must be the last one (so the indices of the
    /// others stay) and not the only one.
    pub fn remove(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        kind: ArtKind,
        index: usize,
    ) -> Result<(), RenderError> {
        let count = self.maps.count(kind);
        if count < 2 || index + 1 != count {
            return Err(RenderError::ArtMap {
                kind,
                index,
                message: format!("only the last of several can be removed (there are {count})"),
            });
        }
        match kind {
            ArtKind::Tam => {
                self.tams.pop();
                self.maps.tams.pop();
                self.all_tams = upload_all_tams(device, queue, &self.maps.tams);
            }
            ArtKind::Sam => {
                self.sams.pop();
                self.maps.sams.pop();
            }
        }
        Ok(())
    }
}
