//! Copying a rendered texture back: rows padded to wgpu's 256-byte copy alignment on the
//! GPU, unpadded here; float targets (Rgba32Float, or Rgba16Float where the adapter cannot
//! render to 32-bit floats) become a linear [`Frame`], 8-bit ones stay bytes.

use crate::render::Frame;
use crate::{Error, Result};
use half::f16;

/// Bytes per pixel of a colour format (4 for anything that is not a float format).
pub fn bytes_per_pixel(format: wgpu::TextureFormat) -> u32 {
    format.block_copy_size(None).unwrap_or(4)
}

/// Bytes per row of the staging buffer for a `width`-pixel row of `bytes_per_pixel`.
pub fn padded_row(width: u32, bytes_per_pixel: u32) -> u32 {
    (width * bytes_per_pixel).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
}

/// A buffer a colour target of `size` and `format` is copied into.
pub fn staging_buffer(
    device: &wgpu::Device,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: padded_row(width, bytes_per_pixel(format)) as u64 * height as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    })
}

/// Records the copy of `texture` into `buffer`.
pub fn copy(encoder: &mut wgpu::CommandEncoder, texture: &wgpu::Texture, buffer: &wgpu::Buffer) {
    let size = texture.size();
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded_row(size.width, bytes_per_pixel(texture.format()))),
                rows_per_image: Some(size.height),
            },
        },
        size,
    );
}

/// Waits for the copy and returns the rows without their padding.
pub fn read_bytes(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    (width, height): (u32, u32),
    bytes_per_pixel: u32,
) -> Result<Vec<u8>> {
    let failed = |what: String| Error::gpu(format!("GPU readback failed: {what}"));
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| failed(e.to_string()))?;
    rx.recv().map_err(|e| failed(e.to_string()))?.map_err(|e| failed(e.to_string()))?;
    let row = (width * bytes_per_pixel) as usize;
    let mut out = Vec::with_capacity(row * height as usize);
    {
        let data = buffer.get_mapped_range(..).map_err(|e| failed(e.to_string()))?;
        for y in 0..height as usize {
            let start = y * padded_row(width, bytes_per_pixel) as usize;
            out.extend_from_slice(&data[start..start + row]);
        }
    }
    buffer.unmap();
    Ok(out)
}

/// Waits for the copy of a float target of `format` and unpacks it into a frame.
pub fn read(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    size: (u32, u32),
    format: wgpu::TextureFormat,
) -> Result<Frame> {
    let bytes = read_bytes(device, buffer, size, bytes_per_pixel(format))?;
    let mut frame = Frame::new(size.0 as usize, size.1 as usize);
    match format {
        wgpu::TextureFormat::Rgba32Float => frame.rgba.copy_from_slice(bytemuck::cast_slice(&bytes)),
        wgpu::TextureFormat::Rgba16Float => {
            for (out, h) in frame.rgba.iter_mut().zip(bytes.chunks_exact(2)) {
                *out = f16::from_le_bytes([h[0], h[1]]).to_f32();
            }
        }
        other => return Err(Error::gpu(format!("GPU readback: {other:?} is not a float format"))),
    }
    Ok(frame)
}

#[cfg(test)]
mod tests {
    #[test]
    fn rows_are_padded_to_256_bytes() {
        assert_eq!(super::padded_row(16, 16), 256);
        assert_eq!(super::padded_row(17, 16), 512);
        assert_eq!(super::padded_row(1024, 16), 16384);
        assert_eq!(super::padded_row(33, 8), 512);
        assert_eq!(super::bytes_per_pixel(wgpu::TextureFormat::Rgba16Float), 8);
    }
}
