//! A board's RAM for a pipeline's state: one region used by nothing else, handed out anew
//! (and initialised) for each configuration as the typed slices [`Settings::storage`] asks
//! for.
//!
//! [`Settings::storage`]: core_nostd::settings::Settings::storage

use core::marker::PhantomData;
use core::mem::{align_of, size_of, MaybeUninit};

/// A block of `N` bytes of RAM for an [`Arena`], aligned for every kind of state (a board
/// places one in a static, in the section of the memory it belongs to).
#[repr(C, align(16))]
pub struct Region<const N: usize>([u8; N]);

/// A region of RAM that slices of state are carved from.
pub struct Arena {
    base: *mut u8,
    len: usize,
}

impl Arena {
    /// # Safety
    /// `base` must point to `len` bytes of RAM, aligned to 16, that nothing else uses for the
    /// rest of the program.
    pub const unsafe fn new(base: *mut u8, len: usize) -> Self {
        Self { base, len }
    }

    /// The arena over a board's static `region`.
    ///
    /// # Safety
    /// Nothing else may use `region` for the rest of the program.
    pub unsafe fn over<const N: usize>(region: *mut MaybeUninit<Region<N>>) -> Self {
        // SAFETY: a `Region` is N bytes aligned to 16; the caller gives it to this arena only.
        unsafe { Self::new(region.cast(), N) }
    }

    /// Bytes in the region.
    pub fn capacity(&self) -> usize {
        self.len
    }

    /// A carver over the whole region, while `self` is borrowed (so no two carvers, and no
    /// slices of an earlier one, live at once).
    pub fn carve(&mut self) -> Carver<'_> {
        Carver {
            base: self.base,
            len: self.len,
            used: 0,
            _region: PhantomData,
        }
    }
}

/// Hands out consecutive, initialised slices of an [`Arena`].
pub struct Carver<'a> {
    base: *mut u8,
    len: usize,
    used: usize,
    _region: PhantomData<&'a mut [u8]>,
}

impl<'a> Carver<'a> {
    /// `n` values of `T`, each `init`; `None` (and nothing taken) when the rest of the region
    /// is too small.
    pub fn take<T: Copy>(&mut self, n: usize, init: T) -> Option<&'a mut [T]> {
        let start = self.used.checked_next_multiple_of(align_of::<T>())?;
        let end = start.checked_add(n.checked_mul(size_of::<T>())?)?;
        if end > self.len {
            return None;
        }
        // SAFETY: `base + start .. base + end` lies in the region (`end <= len`), is aligned
        // for `T` (the region is 16-aligned and `start` a multiple of `align_of::<T>()`, which
        // divides 16 for every type carved here), and no other slice covers it: slices are
        // handed out back to back and live no longer than the borrow of the arena. Every
        // element is written before the slice is made.
        unsafe {
            let p = self.base.add(start).cast::<T>();
            for i in 0..n {
                p.add(i).write(init);
            }
            self.used = end;
            Some(core::slice::from_raw_parts_mut(p, n))
        }
    }
}

/// Bytes a sequence of slices takes in an arena (`(count, size, align)` each, carved in
/// order): what [`Carver::take`] would use.
pub fn bytes_for(slices: &[(usize, usize, usize)]) -> Option<usize> {
    slices.iter().try_fold(0usize, |used, &(n, size, align)| {
        used.checked_next_multiple_of(align)?
            .checked_add(n.checked_mul(size)?)
    })
}
