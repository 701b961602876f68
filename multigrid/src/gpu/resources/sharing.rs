//! Which ranges of `GpuSolver`'s height buffers its gradient field, roughness and rasteriser
//! borrow (see `Buffers`; `resources`' tests check the layout and when each range is live).

#[cfg(test)]
use crate::gpu::params::STENCIL_BYTES;

/// A level-0 buffer of a solver (`resources::LEVEL0` names them in this order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Level0Buf {
    Weight,
    Value,
    Diag,
    F,
    H,
    R,
    Z,
    P,
}

impl Level0Buf {
    /// Every level-0 buffer, in allocation order.
    pub(crate) const ALL: [Level0Buf; 8] = [
        Level0Buf::Weight,
        Level0Buf::Value,
        Level0Buf::Diag,
        Level0Buf::F,
        Level0Buf::H,
        Level0Buf::R,
        Level0Buf::Z,
        Level0Buf::P,
    ];

    /// The name in `resources::LEVEL0` and in the buffer labels (`multigrid.NAME.l0`).
    pub(crate) fn name(self) -> &'static str {
        match self {
            Level0Buf::Weight => "weight",
            Level0Buf::Value => "value",
            Level0Buf::Diag => "diag",
            Level0Buf::F => "f",
            Level0Buf::H => "h",
            Level0Buf::R => "r",
            Level0Buf::Z => "z",
            Level0Buf::P => "p",
        }
    }
}

/// A buffer of `GpuSolver`'s heights that hosts ranges of the fields' level-0 buffers
/// ([`GUEST_LEVEL0`], [`VY_HOME`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Host {
    /// A level-0 buffer (16 units).
    Level0(Level0Buf),
    /// The level-2 stencil records (`stencil[0]`, 6 units), which no field uses.
    Stencil2,
}

impl Host {
    /// Size in units of `n^2 / 16` floats: a level-0 buffer holds 16; the level-2 stencils,
    /// `(n / 4)^2` records of `STENCIL_BYTES`, hold `STENCIL_BYTES / 4` (6).
    #[cfg(test)]
    pub(crate) fn units(self) -> u64 {
        match self {
            Host::Level0(_) => 16,
            Host::Stencil2 => STENCIL_BYTES / 4,
        }
    }
}

impl std::fmt::Display for Host {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Host::Level0(b) => f.write_str(b.name()),
            Host::Stencil2 => f.write_str("stencil2"),
        }
    }
}

/// One field buffer kept inside a heights' buffer: `shift` (1: the gradient field, side `n / 2`,
/// buffers of 4 units; 2: roughness, side `n / 4`, 1 unit), its buffer, its host and offset
/// (units of `n^2 / 16` floats).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Guest {
    pub shift: usize,
    pub buf: Level0Buf,
    pub host: Host,
    pub at: u64,
}

impl Guest {
    /// Size in units of `n^2 / 16` floats.
    #[cfg(test)]
    pub(crate) fn units(&self) -> u64 {
        16 >> (2 * self.shift)
    }
}

const fn guest(shift: usize, buf: Level0Buf, host: Host, at: u64) -> Guest {
    Guest {
        shift,
        buf,
        host,
        at,
    }
}

/// Where `GpuSolver`'s coarser fields keep their level-0 buffers inside the heights' (side `n`)
/// buffers: the heights' level-0 `p`, `diag`, `z` and their level-2 stencils, which no field uses
/// (their coarse levels >= 2 are the heights' levels >= 3). Roughness keeps its own `h` (its warm
/// start reads the last one). `lent_ranges_fit_and_do_not_overlap` checks the layout,
/// `aliased_ranges_are_not_read_after_another_tenant_wrote_them` when each range is live.
pub(crate) const GUEST_LEVEL0: [Guest; 15] = {
    use Level0Buf::*;
    const fn l0(b: Level0Buf) -> Host {
        Host::Level0(b)
    }
    [
        guest(1, Weight, l0(P), 0),
        guest(1, Value, l0(P), 4),
        guest(1, R, l0(P), 8),
        guest(1, Diag, l0(Diag), 0),
        guest(1, F, l0(Diag), 4),
        guest(1, H, l0(Z), 0),
        guest(1, P, l0(Z), 4),
        guest(1, Z, Host::Stencil2, 0),
        guest(2, Weight, l0(P), 12),
        guest(2, Value, l0(P), 13),
        guest(2, R, l0(P), 14),
        guest(2, Diag, l0(Diag), 8),
        guest(2, F, l0(Diag), 9),
        guest(2, P, l0(Z), 8),
        guest(2, Z, Host::Stencil2, 4),
    ]
};

/// The host and offset (units of `n^2 / 16` floats) of the rasteriser's `vy` (the gradient
/// problem's y values, `(n / 2)^2` floats: 4 units).
pub(crate) const VY_HOME: (Host, u64) = (Host::Level0(Level0Buf::Diag), 10);

/// The level-0 buffers a field of side `n >> shift` keeps inside the heights' (side `n`) buffers
/// in `GpuSolver` (`allocated_sizes` leaves them out): all but `h` for roughness (`shift` 2),
/// all eight for the gradient field (`shift` 1); for the heights themselves (`shift` 0) their `f`,
/// which is their own `p`, their `h`, which is mip 0 of the height texture, and their level-1 `u`,
/// `f` and tile-sweep input (`"u.l1"`, `"f.l1"`, `"alt.l1"`), which live in their level-0 `value`
/// and `weight` (see `Buffers`).
pub fn borrowed_level0(shift: usize) -> Vec<&'static str> {
    if shift == 0 {
        return vec!["f", "h", "u.l1", "f.l1", "alt.l1"];
    }
    GUEST_LEVEL0
        .iter()
        .filter(|g| g.shift == shift)
        .map(|g| g.buf.name())
        .collect()
}
