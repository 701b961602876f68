//! Reading buffers and textures back to the CPU (tests, the stop test of FCG, small pyramids).

use super::{GpuContext, GpuError};

/// Bytes `offset .. offset + size` of `src` (which needs `COPY_SRC`), through a temporary staging buffer.
pub(crate) fn read_bytes(
    ctx: &GpuContext,
    src: &wgpu::Buffer,
    offset: u64,
    size: u64,
    what: &str,
) -> Result<Vec<u8>, GpuError> {
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("multigrid.readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("multigrid.readback"),
        });
    enc.copy_buffer_to_buffer(src, offset, &staging, 0, size);
    ctx.submit([enc.finish()]);
    map_read(ctx, &staging, size, what)
}

/// Maps `staging` (MAP_READ) after the submitted work, returns its first `size` bytes and unmaps it.
pub(crate) fn map_read(
    ctx: &GpuContext,
    staging: &wgpu::Buffer,
    size: u64,
    what: &str,
) -> Result<Vec<u8>, GpuError> {
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, 0..size, move |r| {
        let _ = tx.send(r);
    });
    ctx.wait_idle().map_err(|e| GpuError::Readback {
        what: what.to_string(),
        message: e.to_string(),
    })?;
    let mapped = rx.recv().map_err(|e| GpuError::Readback {
        what: what.to_string(),
        message: e.to_string(),
    })?;
    mapped.map_err(|e| GpuError::Readback {
        what: what.to_string(),
        message: e.to_string(),
    })?;
    let bytes = {
        let view = staging
            .get_mapped_range(0..size)
            .map_err(|e| GpuError::Readback {
                what: what.to_string(),
                message: e.to_string(),
            })?;
        view.to_vec()
    };
    staging.unmap();
    ctx.count_down(size);
    Ok(bytes)
}

/// Little-endian f32s of `bytes` (no alignment needed).
pub(crate) fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// `count` f32 starting at element `first` of `src`.
pub(crate) fn read_f32(
    ctx: &GpuContext,
    src: &wgpu::Buffer,
    first: u64,
    count: u64,
    what: &str,
) -> Result<Vec<f32>, GpuError> {
    let bytes = read_bytes(ctx, src, first * 4, count * 4, what)?;
    Ok(f32s(&bytes))
}

/// Row pitch of a texture-to-buffer copy of `width` f32 texels (a multiple of 256 bytes).
pub fn padded_row_bytes(width: u32) -> u32 {
    (width * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// Mip `level` (side `side`) of an R32Float texture (which needs `COPY_SRC`), row 0 first.
pub fn read_texture_r32(
    ctx: &GpuContext,
    tex: &wgpu::Texture,
    level: u32,
    side: u32,
    what: &str,
) -> Result<Vec<f32>, GpuError> {
    let pitch = padded_row_bytes(side);
    let size = pitch as u64 * side as u64;
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("multigrid.readback.texture"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("multigrid.readback.texture"),
        });
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: tex,
            mip_level: level,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &staging,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(pitch),
                rows_per_image: Some(side),
            },
        },
        wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: 1,
        },
    );
    ctx.submit([enc.finish()]);
    let bytes = map_read(ctx, &staging, size, what)?;
    let mut out = Vec::with_capacity((side * side) as usize);
    for row in bytes.chunks_exact(pitch as usize) {
        out.extend(f32s(&row[..side as usize * 4]));
    }
    Ok(out)
}

/// Texels to read from one R32Float texture (which needs `COPY_SRC`): `(x, y)` of mip `level`.
pub struct TexelSet<'a> {
    pub texture: &'a wgpu::Texture,
    pub level: u32,
    pub texels: &'a [[u32; 2]],
}

/// Single texels of several textures: one 4-byte copy each into one staging buffer, one submit and
/// one wait, so only `4 * texels` bytes come back. The caller checks that the texels are inside
/// their levels.
pub fn read_texel_sets(ctx: &GpuContext, sets: &[TexelSet<'_>]) -> Result<Vec<Vec<f32>>, GpuError> {
    let total: usize = sets.iter().map(|s| s.texels.len()).sum();
    if total == 0 {
        return Ok(sets.iter().map(|_| Vec::new()).collect());
    }
    let size = 4 * total as u64;
    ctx.checked("multigrid.read_texels", || {
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("multigrid.readback.texels"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("multigrid.readback.texels"),
            });
        let copies = sets
            .iter()
            .flat_map(|s| s.texels.iter().map(move |t| (s.texture, s.level, t)));
        for (i, (texture, level, t)) in copies.enumerate() {
            enc.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture,
                    mip_level: level,
                    origin: wgpu::Origin3d {
                        x: t[0],
                        y: t[1],
                        z: 0,
                    },
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &staging,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 4 * i as u64,
                        bytes_per_row: None,
                        rows_per_image: None,
                    },
                },
                wgpu::Extent3d {
                    width: 1,
                    height: 1,
                    depth_or_array_layers: 1,
                },
            );
        }
        ctx.submit([enc.finish()]);
        let mut values = f32s(&map_read(ctx, &staging, size, "texels")?).into_iter();
        Ok(sets
            .iter()
            .map(|s| values.by_ref().take(s.texels.len()).collect())
            .collect())
    })
}

/// A staging buffer whose mapping was requested ([`request_map`]) and may not have completed yet.
pub(crate) type MapPending = std::sync::mpsc::Receiver<Result<(), wgpu::BufferAsyncError>>;

/// Requests the mapping of `staging`'s first `size` bytes after the submitted work, without waiting.
pub(crate) fn request_map(staging: &wgpu::Buffer, size: u64) -> MapPending {
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, 0..size, move |r| {
        let _ = tx.send(r);
    });
    rx
}

/// The bytes of a requested mapping, then unmapped: at once when it completed, after a blocking
/// wait when `wait`, else `Ok(None)` (still pending; poll the device and ask again).
pub(crate) fn finish_map(
    ctx: &GpuContext,
    staging: &wgpu::Buffer,
    size: u64,
    pending: &MapPending,
    wait: bool,
    what: &str,
) -> Result<Option<Vec<u8>>, GpuError> {
    let err = |m: String| GpuError::Readback {
        what: what.to_string(),
        message: m,
    };
    let mapped = match pending.try_recv() {
        Ok(r) => r,
        Err(std::sync::mpsc::TryRecvError::Empty) if wait => {
            ctx.wait_idle().map_err(|e| err(e.to_string()))?;
            pending.recv().map_err(|e| err(e.to_string()))?
        }
        Err(std::sync::mpsc::TryRecvError::Empty) => return Ok(None),
        Err(e) => return Err(err(e.to_string())),
    };
    mapped.map_err(|e| err(e.to_string()))?;
    let bytes = staging
        .get_mapped_range(0..size)
        .map_err(|e| err(e.to_string()))?
        .to_vec();
    staging.unmap();
    ctx.count_down(size);
    Ok(Some(bytes))
}

#[cfg(test)]
mod tests {
    #[test]
    fn row_pitch_is_aligned() {
        assert_eq!(super::padded_row_bytes(1), 256);
        assert_eq!(super::padded_row_bytes(64), 256);
        assert_eq!(super::padded_row_bytes(65), 512);
        assert_eq!(super::padded_row_bytes(1024), 4096);
    }
}
