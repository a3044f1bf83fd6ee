//! Copying a rendered Rgba32Float texture back into a [`Frame`]: rows padded to wgpu's
//! 256-byte copy alignment on the GPU, unpadded here.

use crate::render::Frame;
use crate::{Error, Result};

const BYTES_PER_PIXEL: u32 = 16;

/// Bytes per row of the staging buffer for a `width`-pixel row.
pub fn padded_row(width: u32) -> u32 {
    (width * BYTES_PER_PIXEL).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
}

/// A buffer the colour target of `size` is copied into.
pub fn staging_buffer(device: &wgpu::Device, (width, height): (u32, u32)) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: padded_row(width) as u64 * height as u64,
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
                bytes_per_row: Some(padded_row(size.width)),
                rows_per_image: Some(size.height),
            },
        },
        size,
    );
}

/// Waits for the copy and unpacks the rows.
pub fn read(device: &wgpu::Device, buffer: &wgpu::Buffer, (width, height): (u32, u32)) -> Result<Frame> {
    let failed = |what: String| Error::invalid(format!("GPU readback failed: {what}"));
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| failed(e.to_string()))?;
    rx.recv().map_err(|e| failed(e.to_string()))?.map_err(|e| failed(e.to_string()))?;
    let mut frame = Frame::new(width as usize, height as usize);
    {
        let data = buffer.get_mapped_range(..).map_err(|e| failed(e.to_string()))?;
        let row = (width * BYTES_PER_PIXEL) as usize;
        for (y, out) in frame.rgba.chunks_exact_mut(width as usize * 4).enumerate() {
            let start = y * padded_row(width) as usize;
            out.copy_from_slice(bytemuck::cast_slice(&data[start..start + row]));
        }
    }
    buffer.unmap();
    Ok(frame)
}

#[cfg(test)]
mod tests {
    #[test]
    fn rows_are_padded_to_256_bytes() {
        assert_eq!(super::padded_row(16), 256);
        assert_eq!(super::padded_row(17), 512);
        assert_eq!(super::padded_row(1024), 16384);
    }
}
