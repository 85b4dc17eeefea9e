//! The renderer's own colour + depth texture (with an optional multisampled colour buffer
//! resolved into the colour texture), which the app shows as an egui image and the offscreen
//! path reads back into an image.

use std::time::Duration;

use super::RenderError;

/// Depth buffer format (reversed-Z: cleared to 0, compared with `Greater`).
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// How long a read-back waits for the GPU before giving up.
pub const READBACK_TIMEOUT: Duration = Duration::from_secs(30);

/// A colour texture (single-sampled, sampleable, copyable) plus depth, of one size.
#[derive(Debug)]
pub struct RenderTarget {
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    msaa_view: Option<wgpu::TextureView>,
    depth_view: wgpu::TextureView,
    size: [u32; 2],
    format: wgpu::TextureFormat,
    sample_count: u32,
}

impl RenderTarget {
    /// Creates a target of `size` pixels (each side clamped to 1..=the device limit) in
    /// `format` with `sample_count` samples per pixel (1 or 4).
    pub fn new(
        device: &wgpu::Device,
        size: [u32; 2],
        format: wgpu::TextureFormat,
        sample_count: u32,
    ) -> Self {
        let max = device.limits().max_texture_dimension_2d.max(1);
        let size = [size[0].clamp(1, max), size[1].clamp(1, max)];
        let sample_count = if sample_count > 1 { 4 } else { 1 };
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        let color = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("neural-cloth viewport colour"),
            size: extent,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let color_view = color.create_view(&wgpu::TextureViewDescriptor {
            label: Some("neural-cloth viewport colour view"),
            ..Default::default()
        });
        let msaa_view = (sample_count > 1).then(|| {
            device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some("neural-cloth viewport multisampled colour"),
                    size: extent,
                    mip_level_count: 1,
                    sample_count,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor {
                    label: Some("neural-cloth viewport multisampled colour view"),
                    ..Default::default()
                })
        });
        let depth_view = device
            .create_texture(&wgpu::TextureDescriptor {
                label: Some("neural-cloth viewport depth"),
                size: extent,
                mip_level_count: 1,
                sample_count,
                dimension: wgpu::TextureDimension::D2,
                format: DEPTH_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            })
            .create_view(&wgpu::TextureViewDescriptor {
                label: Some("neural-cloth viewport depth view"),
                ..Default::default()
            });
        Self {
            color,
            color_view,
            msaa_view,
            depth_view,
            size,
            format,
            sample_count,
        }
    }

    /// Size in pixels `[width, height]`.
    pub fn size(&self) -> [u32; 2] {
        self.size
    }

    /// Width divided by height.
    pub fn aspect(&self) -> f32 {
        self.size[0] as f32 / self.size[1].max(1) as f32
    }

    /// Colour format.
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// Samples per pixel of the colour and depth attachments.
    pub fn sample_count(&self) -> u32 {
        self.sample_count
    }

    /// A view of the resolved colour texture, for `register_native_texture`.
    pub fn color_view(&self) -> &wgpu::TextureView {
        &self.color_view
    }

    /// Colour attachment of a render pass that clears to `clear` and resolves if multisampled.
    pub(crate) fn color_attachment(
        &self,
        clear: wgpu::Color,
    ) -> wgpu::RenderPassColorAttachment<'_> {
        let (view, resolve_target, store) = match &self.msaa_view {
            Some(msaa) => (msaa, Some(&self.color_view), wgpu::StoreOp::Discard),
            None => (&self.color_view, None, wgpu::StoreOp::Store),
        };
        wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(clear),
                store,
            },
        }
    }

    /// Depth attachment cleared to 0 (reversed-Z far).
    pub(crate) fn depth_attachment(&self) -> wgpu::RenderPassDepthStencilAttachment<'_> {
        wgpu::RenderPassDepthStencilAttachment {
            view: &self.depth_view,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(0.0),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }
    }

    /// Copies the colour texture into an RGBA image, blocking until the GPU is done.
    /// Only 4-byte RGBA/BGRA 8-bit formats are supported (BGRA is swizzled to RGBA).
    pub fn read_image(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<image::RgbaImage, RenderError> {
        let bgra = match self.format {
            wgpu::TextureFormat::Rgba8Unorm | wgpu::TextureFormat::Rgba8UnormSrgb => false,
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb => true,
            other => {
                return Err(RenderError::Readback(format!(
                    "unsupported format {other:?}"
                )));
            }
        };
        let [width, height] = self.size;
        let unpadded = width as usize * 4;
        let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as usize;
        let padded = unpadded.div_ceil(align) * align;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("neural-cloth readback buffer"),
            size: (padded * height as usize) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("neural-cloth readback encoder"),
        });
        encoder.copy_texture_to_buffer(
            self.color.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded as u32),
                    rows_per_image: None,
                },
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
        let submission = queue.submit(std::iter::once(encoder.finish()));
        let slice = buffer.slice(..);
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |result| drop(sender.send(result)));
        device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(submission),
                timeout: Some(READBACK_TIMEOUT),
            })
            .map_err(|e| RenderError::Readback(format!("waiting for the GPU: {e}")))?;
        receiver
            .recv_timeout(READBACK_TIMEOUT)
            .map_err(|e| RenderError::Readback(format!("map callback never ran: {e}")))?
            .map_err(|e| RenderError::Readback(format!("mapping the buffer: {e}")))?;
        let data = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| RenderError::Readback(format!("mapped range: {e}")))?;
            let mut data = Vec::with_capacity(unpadded * height as usize);
            for row in view.chunks_exact(padded) {
                data.extend_from_slice(row.get(..unpadded).unwrap_or_default());
            }
            data
        };
        buffer.unmap();
        let mut data = data;
        if bgra {
            for px in data.chunks_exact_mut(4) {
                px.swap(0, 2);
            }
        }
        image::RgbaImage::from_raw(width, height, data)
            .ok_or_else(|| RenderError::Readback("image size mismatch".into()))
    }
}
