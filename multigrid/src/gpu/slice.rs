//! A range of a GPU buffer: what pass tables bind and resources lend between fields.

/// A range of a buffer (offset and size in bytes), bound as a `wgpu::BufferBinding`: a whole
/// buffer, or a range of a height buffer lent to a coarser field (see `resources::Buffers`).
#[derive(Clone, Debug)]
pub(crate) struct Slice {
    pub buffer: wgpu::Buffer,
    pub offset: u64,
    pub size: u64,
}

impl Slice {
    /// All of `buffer`.
    pub fn whole(buffer: wgpu::Buffer) -> Slice {
        Slice {
            offset: 0,
            size: buffer.size(),
            buffer,
        }
    }

    /// `size` bytes of this range from `offset` (bytes into it); `None` when they do not fit.
    pub fn part(&self, offset: u64, size: u64) -> Option<Slice> {
        (offset.checked_add(size)? <= self.size).then(|| Slice {
            buffer: self.buffer.clone(),
            offset: self.offset + offset,
            size,
        })
    }

    /// Offset in f32 values (for readbacks).
    pub fn first_f32(&self) -> u64 {
        self.offset / 4
    }

    /// Clears the range.
    pub fn clear(&self, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.buffer, self.offset, Some(self.size));
    }

    /// Copies `min(self.size, to.size)` bytes into `to` (another buffer).
    pub fn copy_to(&self, enc: &mut wgpu::CommandEncoder, to: &Slice) {
        enc.copy_buffer_to_buffer(
            &self.buffer,
            self.offset,
            &to.buffer,
            to.offset,
            self.size.min(to.size),
        );
    }
}
