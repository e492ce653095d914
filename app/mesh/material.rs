//! Surface colour as mesh data: materials (a base colour factor and an optional texture), decoded textures with
//! their sampler settings, and per triangle the material, texture coordinates and vertex colours. Loaders fill a
//! [`Shading`] only when the file carries colour; the voxel colour pass (`voxel/colour.rs`, `gpu/colour.rs`)
//! evaluates it at the surface point nearest each voxel centre.
//!
//! Colours are kept in linear RGB (glTF factors and vertex colours are linear; texels are sRGB-encoded and decoded
//! when sampled, through [`SRGB_TO_LINEAR`], the one table the CPU reference and the shader share).

use glam::{Vec2, Vec4};

/// How a texture coordinate outside [0, 1] is brought back (glTF sampler `wrapS`/`wrapT`; OBJ textures repeat).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[repr(u32)]
pub enum Wrap {
    #[default]
    Repeat = 0,
    ClampToEdge = 1,
    MirroredRepeat = 2,
}

/// A decoded texture: `width × height` texels, row 0 at the top (v = 0), each RGBA8 packed as
/// `r | g << 8 | b << 16 | a << 24` with sRGB-encoded colour and linear alpha.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<u32>,
    pub wrap: [Wrap; 2],
    /// Nearest-texel sampling (glTF `magFilter` NEAREST); otherwise bilinear.
    pub nearest: bool,
}

/// The most a texture's decoded RGBA8 may take: the image crate's own limit on a decoder's allocations, checked
/// first from the header so that the refusal says what the image declares.
const TEXTURE_BYTES: u64 = 512 << 20;

impl Texture {
    /// Decodes an encoded image (PNG, JPEG or WebP, guessed from its bytes) into RGBA8, within `budget`: the
    /// decoder may allocate no more than what is left of it (and no more than the image crate's default of
    /// 512 MiB), and the texels are counted against it.
    pub(crate) fn decode(
        bytes: &[u8],
        wrap: [Wrap; 2],
        nearest: bool,
        budget: &super::files::Budget,
    ) -> Result<Texture, String> {
        // The size from the header first: an image over the budget is refused before it is decoded. The decoder
        // itself stays within the image crate's default limits (512 MiB).
        let (width, height) = image_dimensions(bytes)?;
        if width == 0 || height == 0 {
            return Err("the image is empty".into());
        }
        let texel_bytes = width as u64 * height as u64 * 4;
        if texel_bytes > TEXTURE_BYTES {
            let human = crate::memory::human;
            return Err(format!(
                "declares {width}x{height} pixels, {} decoded, more than a texture may take ({})",
                human(texel_bytes),
                human(TEXTURE_BYTES)
            ));
        }
        budget.spend(texel_bytes).map_err(|total| format!("decoded, it {}", budget.over(texel_bytes, total)))?;
        let image = decode_image(bytes)?.into_rgba8();
        let (width, height) = image.dimensions();
        let texels = image.pixels().map(|p| u32::from_le_bytes(p.0)).collect();
        Ok(Texture { width, height, texels, wrap, nearest })
    }
}

/// An image's size from its header: PNG, JPEG or WebP guessed from its bytes, or PNG alone in the page's app
/// ([`super::DECODES_ALL`]: there the image crate's format guess, which reaches every decoder, is not linked).
fn image_dimensions(bytes: &[u8]) -> Result<(u32, u32), String> {
    use image::ImageDecoder;
    if super::DECODES_ALL {
        let reader = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format();
        reader.map_err(|e| e.to_string())?.into_dimensions().map_err(|e| e.to_string())
    } else {
        only_png(bytes)?;
        let decoder = image::codecs::png::PngDecoder::with_limits(std::io::Cursor::new(bytes), Default::default());
        Ok(decoder.map_err(|e| e.to_string())?.dimensions())
    }
}

/// An image decoded, as [`image_dimensions`] reads it, within the image crate's default limits (512 MiB).
fn decode_image(bytes: &[u8]) -> Result<image::DynamicImage, String> {
    if super::DECODES_ALL {
        let reader = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format();
        reader.map_err(|e| e.to_string())?.decode().map_err(|e| e.to_string())
    } else {
        only_png(bytes)?;
        decode_png(bytes, image::Limits::default()).map_err(|e| e.to_string())
    }
}

/// In the page's app, an image that is not a PNG fails as `ImageReader` fails on a format it is built without
/// (JPEG and WebP never get here: the loader module reads the files that have them).
fn only_png(bytes: &[u8]) -> Result<(), String> {
    use image::error::{ImageError, ImageFormatHint};
    match image::guess_format(bytes) {
        Ok(image::ImageFormat::Png) => Ok(()),
        Ok(format) => Err(ImageError::Unsupported(ImageFormatHint::Exact(format).into()).to_string()),
        Err(e) => Err(e.to_string()),
    }
}

/// A PNG decoded by the PNG decoder itself within `limits`, applied as `ImageReader::decode` applies them: the
/// decoder's own allocations, then the decoded image's bytes. For the page's app, which links no other decoder
/// (`ImageReader`'s decode reaches every format the image crate is built with), and for palettes.
pub(crate) fn decode_png(bytes: &[u8], mut limits: image::Limits) -> image::ImageResult<image::DynamicImage> {
    use image::ImageDecoder;
    let mut decoder = image::codecs::png::PngDecoder::with_limits(std::io::Cursor::new(bytes), limits.clone())?;
    limits.reserve(decoder.total_bytes())?;
    decoder.set_limits(limits)?;
    image::DynamicImage::from_decoder(decoder)
}

/// A texture as a material uses it: which one, and the `KHR_texture_transform` of its coordinates as the two
/// rows of a 2×3 matrix (`uv' = (row0 · (u, v, 1), row1 · (u, v, 1))`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TextureRef {
    pub texture: u32,
    pub transform: [[f32; 3]; 2],
}

impl TextureRef {
    pub const IDENTITY: [[f32; 3]; 2] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    /// The transform of `KHR_texture_transform`: scale, then rotate (counter-clockwise in uv, as the extension
    /// defines it), then translate.
    pub fn transform_from(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> [[f32; 3]; 2] {
        let (s, c) = rotation.sin_cos();
        [[c * scale[0], s * scale[1], offset[0]], [-s * scale[0], c * scale[1], offset[1]]]
    }
}

/// What a material's alpha (base colour alpha × texture alpha × vertex colour alpha) means: glTF's `alphaMode`.
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub enum AlphaMode {
    /// Alpha is ignored: every surface point is there (glTF's default).
    #[default]
    Opaque,
    /// A cut-out (glTF `MASK` with its `alphaCutoff`, OBJ `map_d`): a surface point whose alpha is below the
    /// cutoff is not there. It sets no voxel of a surface grid and gives no voxel its colour.
    Mask(f32),
    /// Blended: every point is there; alpha is the colour's opacity.
    Blend,
}

/// glTF's `alphaCutoff` when a `MASK` material gives none, and meshvox's for OBJ materials with a `map_d`.
pub const DEFAULT_ALPHA_CUTOFF: f32 = 0.5;

/// A material's colour: `base_color × texture(uv)`, linear RGBA, and what its alpha means.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Material {
    pub name: String,
    pub base_color: Vec4,
    pub texture: Option<TextureRef>,
    pub alpha: AlphaMode,
}

impl Default for Material {
    /// glTF's default material: white, untextured, opaque.
    fn default() -> Material {
        Material { name: String::new(), base_color: Vec4::ONE, texture: None, alpha: AlphaMode::Opaque }
    }
}

impl Material {
    /// The alpha below which a surface point of this material is cut out: 0 (nothing is) unless it masks, and
    /// 0 for a cutoff that is not a number in (0, 1].
    pub fn cutoff(&self) -> f32 {
        match self.alpha {
            AlphaMode::Mask(c) if c > 0.0 => c.min(1.0),
            _ => 0.0,
        }
    }

    /// Whether the voxels this material colours keep their alpha (`BLEND`); other voxels are opaque (255).
    pub fn keeps_alpha(&self) -> bool {
        self.alpha == AlphaMode::Blend
    }

    /// The material's alpha rule as the colour passes read it (word 11 of its record): the cutoff where it masks,
    /// -1 where it blends (the alpha kept), else 0.
    pub fn alpha_rule(&self) -> f32 {
        if self.keeps_alpha() { -1.0 } else { self.cutoff() }
    }
}

/// Per-triangle shading inputs, laid out as the colour shader reads them (`TriangleShading` in
/// `shaders/colour.wgsl`): three texture coordinates, three vertex colours in linear unorm16 RGBA, the material.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable, serde::Serialize, serde::Deserialize)]
pub struct TriangleShading {
    pub uv: [[f32; 2]; 3],
    /// Linear RGBA per corner, each channel `round(c × 65535)`, packed two channels per u32 (r | g << 16, b | a << 16).
    pub color: [[u32; 2]; 3],
    pub material: u32,
    pub _pad: u32,
}

impl TriangleShading {
    /// A corner colour packed as the shader reads it.
    pub fn pack_color(c: Vec4) -> [u32; 2] {
        let q = |x: f32| (x.clamp(0.0, 1.0) * 65535.0).round() as u32;
        [q(c.x) | q(c.y) << 16, q(c.z) | q(c.w) << 16]
    }

    pub const WHITE: [u32; 2] = [0xffff_ffff, 0xffff_ffff];

    /// A triangle with `material`, no texture coordinates and white corners.
    pub fn plain(material: u32) -> TriangleShading {
        TriangleShading { uv: [[0.0; 2]; 3], color: [Self::WHITE; 3], material, _pad: 0 }
    }

    /// Corner `i`'s colour, unpacked.
    pub fn corner_color(&self, i: usize) -> Vec4 {
        let [a, b] = self.color[i];
        let f = |x: u32| (x & 0xffff) as f32 / 65535.0;
        Vec4::new(f(a), f(a >> 16), f(b), f(b >> 16))
    }

    pub fn corner_uv(&self, i: usize) -> Vec2 {
        Vec2::from(self.uv[i])
    }
}

/// Everything the colour pass needs from a mesh: `triangles[i]` shades `Mesh::triangles[i]`.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Shading {
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub triangles: Vec<TriangleShading>,
}

impl Shading {
    /// Whether any surface has a colour other than white: a texture, vertex colours or a coloured material (or a
    /// material that cuts out what its alpha hides). An opacity alone (OBJ's `d`) is no colour. A mesh without
    /// any is drawn and exported in the viewer's flat colour.
    pub fn has_colour(&self) -> bool {
        let used = |m: &Material| m.texture.is_some() || m.base_color.truncate() != glam::Vec3::ONE || m.cutoff() > 0.0;
        self.materials.iter().any(used) || self.triangles.iter().any(|t| t.color != [TriangleShading::WHITE; 3])
    }

    /// Whether a material cuts out what its alpha hides ([`AlphaMode::Mask`]): then the colour pass decides
    /// which surface voxels are there, too.
    pub fn cuts_out(&self) -> bool {
        self.materials.iter().any(|m| m.cutoff() > 0.0)
    }
}

/// sRGB-encoded byte → linear value, the table both the CPU reference and the shader decode texels with (so
/// both sides use the same numbers rather than two `pow` implementations).
pub static SRGB_TO_LINEAR: std::sync::LazyLock<[f32; 256]> = std::sync::LazyLock::new(|| {
    std::array::from_fn(|i| {
        let c = i as f64 / 255.0;
        (if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }) as f32
    })
});
