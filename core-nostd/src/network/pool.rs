//! The unit pool: unit state only for the cells whose units are not at rest.
//!
//! A dense spiking network keeps one [`super::UnitPair`] (48 bytes) per cell; most of them are
//! at rest at any moment. A pooled network keeps a fixed number of pair slots instead, and each
//! cell's [`super::Cell`] names its slot (or none). A cell takes a slot when an event drives
//! one of its units and gives it back once both units are at rest
//! ([`crate::unit::Kernel::burst_at_rest`]), which a sweep over the slots finds (a full pass
//! every [`SWEEP_TICKS`] output periods) and the round-robin refresh of the cells too. A
//! pooled network takes the next input of a unit at rest as an idle one's whether or not its
//! slot was freed yet, so while the pool has room its spikes do not depend on the pool's size
//! or on when the sweep comes by (tested, for streams in time order). They differ from the
//! dense network's only by what the rest rule drops: -0.0075 % of the spikes on dev03.
//!
//! # When the pool is full
//! An event whose cell has no slot and finds none free does not reach its units (they stay at
//! rest; the event's trigger record and FAC traces are unaffected). It is counted in
//! [`super::NetStats::pool_full`], and the pipeline flags the next sample
//! [`crate::flags::OVERFLOW`]. Nothing else changes: no other cell's units are touched.
//!
//! # Memory
//! Per slot: the pair (48 bytes) and its owner (4 bytes); per cell: nothing more (the slot
//! index lives in the cell's word that a dense network uses for the slow FAC trace; a pooled
//! network keeps no slow traces).

/// A sweep visits every slot once per this many output periods.
pub const SWEEP_TICKS: usize = 32;

/// Owner word of a free slot: this bit, and the next free slot in the low bits.
const FREE: u32 = 1 << 31;

/// End of the free list.
const NIL: u32 = FREE - 1;

/// Slot bookkeeping of a pooled network: who owns each slot, the free list, counters.
pub(super) struct Pool<'a> {
    /// Per slot: the owning cell, or [`FREE`] `|` the next free slot.
    owners: &'a mut [u32],
    /// First free slot ([`NIL`]: none).
    free: u32,
    /// Slots in use now and at most.
    used: u32,
    peak: u32,
    /// Next slot the sweep looks at.
    sweep: usize,
}

/// How full a unit pool is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PoolUse {
    /// Slots (unit pairs) in the pool.
    pub capacity: usize,
    /// Slots in use now.
    pub used: usize,
    /// Most slots in use at once so far.
    pub peak: usize,
}

impl<'a> Pool<'a> {
    /// A pool over `owners` (one word per slot), every slot free.
    pub(super) fn new(owners: &'a mut [u32]) -> Self {
        let n = owners.len();
        for (i, o) in owners.iter_mut().enumerate() {
            *o = if i + 1 < n {
                FREE | (i as u32 + 1)
            } else {
                FREE | NIL
            };
        }
        Self {
            owners,
            free: if n == 0 { NIL } else { 0 },
            used: 0,
            peak: 0,
            sweep: 0,
        }
    }

    /// A free slot, now owned by `cell`; `None` when the pool is full.
    #[inline]
    pub(super) fn take(&mut self, cell: usize) -> Option<usize> {
        let slot = self.free as usize;
        let owner = self.owners.get_mut(slot)?;
        self.free = *owner & !FREE;
        *owner = cell as u32;
        self.used += 1;
        self.peak = self.peak.max(self.used);
        Some(slot)
    }

    /// Gives `slot` back.
    #[inline]
    pub(super) fn give_back(&mut self, slot: usize) {
        if let Some(owner) = self.owners.get_mut(slot) {
            if *owner & FREE == 0 {
                *owner = FREE | self.free;
                self.free = slot as u32;
                self.used -= 1;
            }
        }
    }

    /// The owner word of every slot (see [`Pool::cell_of_word`]).
    #[inline]
    pub(super) fn owners(&self) -> &[u32] {
        self.owners
    }

    /// The cell an owner word names, if it is a cell's (the slot is in use), not a free
    /// slot's.
    #[inline(always)]
    pub(super) const fn cell_of_word(word: u32) -> Option<usize> {
        if word & FREE == 0 {
            Some(word as usize)
        } else {
            None
        }
    }

    /// The cell owning `slot`, if it is in use.
    #[inline]
    pub(super) fn owner(&self, slot: usize) -> Option<usize> {
        self.owners.get(slot).copied().and_then(Self::cell_of_word)
    }

    /// The slots the sweep looks at this period: the next `len / SWEEP_TICKS` (at least 1),
    /// as a start and a count (wrapping at the end).
    #[inline]
    pub(super) fn sweep_range(&mut self) -> (usize, usize) {
        let n = self.owners.len();
        if n == 0 {
            return (0, 0);
        }
        let count = n.div_ceil(SWEEP_TICKS);
        let start = self.sweep % n;
        self.sweep = (start + count) % n;
        (start, count)
    }

    /// Slots in the pool.
    pub(super) fn capacity(&self) -> usize {
        self.owners.len()
    }

    /// How full the pool is.
    pub(super) fn usage(&self) -> PoolUse {
        PoolUse {
            capacity: self.owners.len(),
            used: self.used as usize,
            peak: self.peak as usize,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_are_taken_and_given_back_through_the_free_list() {
        let mut owners = [0u32; 3];
        let mut p = Pool::new(&mut owners);
        assert_eq!(p.take(7), Some(0));
        assert_eq!(p.take(8), Some(1));
        assert_eq!(p.take(9), Some(2));
        assert_eq!(p.take(10), None);
        assert_eq!(p.owner(1), Some(8));
        p.give_back(1);
        p.give_back(1); // twice: no effect
        assert_eq!(p.owner(1), None);
        assert_eq!(
            p.usage(),
            PoolUse {
                capacity: 3,
                used: 2,
                peak: 3
            }
        );
        assert_eq!(p.take(11), Some(1));
        assert_eq!(p.take(12), None);
    }

    #[test]
    fn an_empty_pool_is_always_full() {
        let mut p = Pool::new(&mut []);
        assert_eq!(p.take(0), None);
        assert_eq!(p.sweep_range(), (0, 0));
    }

    #[test]
    fn the_sweep_covers_every_slot_in_sweep_ticks_periods() {
        let mut owners = [0u32; 100];
        let mut p = Pool::new(&mut owners);
        let mut seen = [0u32; 100];
        for _ in 0..SWEEP_TICKS {
            let (start, count) = p.sweep_range();
            for i in 0..count {
                seen[(start + i) % 100] += 1;
            }
        }
        assert!(seen.iter().all(|&n| n >= 1));
    }
}
