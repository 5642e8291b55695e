//! Network layouts: which pixels carry TDE units, and where their state lives.
//!
//! Storage is organised by *cell*: one cell per pixel that the layout uses. A cell holds that
//! pixel's FAC trace and the (up to) two units that the pixel *triggers*:
//! - [`Dir::LeftToRight`]: FAC = `(x - s, y)`, TRG = `(x, y)` — prefers motion to the right;
//! - [`Dir::RightToLeft`]: FAC = `(x + s, y)`, TRG = `(x, y)` — prefers motion to the left.
//!
//! An event at a pixel therefore updates one FAC trace and triggers at most the two units of the
//! same cell, reading the FAC traces of the cells `s` pixels to its left and right.

/// Orientation of a unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dir {
    /// FAC on the left, TRG on the right: responds to rightward image motion.
    LeftToRight = 0,
    /// FAC on the right, TRG on the left: responds to leftward image motion.
    RightToLeft = 1,
}

impl Dir {
    /// Both orientations, in slot order.
    pub const BOTH: [Dir; 2] = [Dir::LeftToRight, Dir::RightToLeft];

    /// Slot of this orientation inside a cell (0 or 1).
    pub const fn slot(self) -> usize {
        self as usize
    }

    /// Horizontal offset (pixels, times the stride) from the TRG pixel to the FAC pixel.
    pub const fn fac_offset_sign(self) -> i32 {
        match self {
            Dir::LeftToRight => -1,
            Dir::RightToLeft => 1,
        }
    }
}

/// Which units exist in a cell: bit 0 = left-to-right, bit 1 = right-to-left.
pub type UnitMask = u8;

/// A network layout: a map from pixels to cells, and which units each cell has.
pub trait Layout {
    /// Number of cells (state slots) the layout needs.
    fn cell_count(&self) -> usize;
    /// Number of units in the layout.
    fn unit_count(&self) -> usize;
    /// FAC-to-TRG distance in pixels.
    fn stride(&self) -> u16;
    /// Sensor width and height in pixels (events outside are ignored).
    fn sensor(&self) -> (u16, u16);
    /// The cell of pixel `(x, y)`, if the layout uses that pixel.
    fn cell(&self, x: u16, y: u16) -> Option<usize>;
    /// Units present in cell `cell`.
    fn units(&self, cell: usize) -> UnitMask;
    /// Pixel coordinates of cell `cell`.
    fn pixel(&self, cell: usize) -> (u16, u16);

    /// Units present in `cell`, the cell of pixel `(x, y)` (a layout may answer faster when it
    /// knows the pixel).
    #[inline]
    fn units_at(&self, _x: u16, _y: u16, cell: usize) -> UnitMask {
        self.units(cell)
    }

    /// The cell `dx` pixels to the right of pixel `(x, y)` (whose cell is `cell`), if used.
    #[inline]
    fn neighbor(&self, x: u16, y: u16, _cell: usize, dx: i32) -> Option<usize> {
        let nx = u16::try_from(i32::from(x) + dx).ok()?;
        self.cell(nx, y)
    }
}

/// Every pixel pair at the stride, both orientations, over a window of the sensor.
///
/// With the full 346 x 260 sensor and stride 2 this is the paper's 178,880 units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dense {
    sensor_w: u16,
    sensor_h: u16,
    x0: u16,
    y0: u16,
    w: u16,
    h: u16,
    stride: u16,
}

impl Dense {
    /// The whole sensor. `stride` must be at least 1 and smaller than `width`.
    pub const fn new(width: u16, height: u16, stride: u16) -> Option<Self> {
        Self::window(width, height, 0, 0, width, height, stride)
    }

    /// A `w` x `h` window at `(x0, y0)` of a `width` x `height` sensor.
    pub const fn window(
        width: u16,
        height: u16,
        x0: u16,
        y0: u16,
        w: u16,
        h: u16,
        stride: u16,
    ) -> Option<Self> {
        if stride == 0 || w <= stride || h == 0 {
            return None;
        }
        if x0 as u32 + w as u32 > width as u32 || y0 as u32 + h as u32 > height as u32 {
            return None;
        }
        Some(Self {
            sensor_w: width,
            sensor_h: height,
            x0,
            y0,
            w,
            h,
            stride,
        })
    }

    /// Window width and height.
    pub const fn size(&self) -> (u16, u16) {
        (self.w, self.h)
    }
}

impl Layout for Dense {
    fn cell_count(&self) -> usize {
        self.w as usize * self.h as usize
    }

    fn unit_count(&self) -> usize {
        2 * (self.w - self.stride) as usize * self.h as usize
    }

    fn stride(&self) -> u16 {
        self.stride
    }

    fn sensor(&self) -> (u16, u16) {
        (self.sensor_w, self.sensor_h)
    }

    #[inline]
    fn cell(&self, x: u16, y: u16) -> Option<usize> {
        let cx = x.checked_sub(self.x0)?;
        let cy = y.checked_sub(self.y0)?;
        if cx >= self.w || cy >= self.h {
            return None;
        }
        Some(cy as usize * self.w as usize + cx as usize)
    }

    #[inline]
    fn units(&self, cell: usize) -> UnitMask {
        let w = self.w as usize;
        let cx = if w == 0 { 0 } else { cell % w };
        let s = self.stride as usize;
        let lr = u8::from(cx >= s);
        let rl = u8::from(cx + s < w);
        lr | (rl << 1)
    }

    #[inline]
    fn units_at(&self, x: u16, _y: u16, _cell: usize) -> UnitMask {
        let cx = x.wrapping_sub(self.x0);
        let lr = u8::from(cx >= self.stride);
        let rl = u8::from(u32::from(cx) + u32::from(self.stride) < u32::from(self.w));
        lr | (rl << 1)
    }

    #[inline]
    fn neighbor(&self, x: u16, _y: u16, cell: usize, dx: i32) -> Option<usize> {
        // Within the window's row: the cell index moves by dx.
        let cx = i32::from(x.wrapping_sub(self.x0)) + dx;
        if cx < 0 || cx >= i32::from(self.w) {
            return None;
        }
        usize::try_from(cell as i64 + i64::from(dx)).ok()
    }

    fn pixel(&self, cell: usize) -> (u16, u16) {
        let w = self.w as usize;
        if w == 0 {
            return (self.x0, self.y0);
        }
        let cx = (cell % w) as u16;
        let cy = (cell / w) as u16;
        (self.x0.saturating_add(cx), self.y0.saturating_add(cy))
    }
}

/// Side of one paper box (pixels).
pub const BOX_SIZE: u16 = 20;
/// Units per box.
pub const UNITS_PER_BOX: usize = 100;
/// Horizontal offset of each box centre from the image centre (pixels).
pub const BOX_OFFSET_X: u16 = 100;
/// Cells per box.
const BOX_CELLS: usize = BOX_SIZE as usize * BOX_SIZE as usize;

/// The paper's on-chip layout: two 20 x 20 pixel boxes, vertically centred, their centres 100 px
/// left and right of the image centre; in each box 100 units at seeded random positions, half
/// left-to-right and half right-to-left, stride 2, both boxes with the same placement.
///
/// Cells are the boxes' pixels (800); a unit lives in the cell of its TRG pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PaperBoxes {
    sensor_w: u16,
    sensor_h: u16,
    stride: u16,
    /// Top-left corners of the left and right box.
    origin: [(u16, u16); 2],
    /// Units per box cell (the same for both boxes).
    mask: [UnitMask; BOX_CELLS],
}

impl PaperBoxes {
    /// Placement seed the tools and the firmware use by default.
    pub const DEFAULT_SEED: u64 = 1;

    /// The layout on a `width` x `height` sensor with placement seed `seed` and stride 2.
    /// `None` when the boxes do not fit on the sensor.
    pub fn new(width: u16, height: u16, seed: u64) -> Option<Self> {
        Self::with_stride(width, height, 2, seed)
    }

    /// Same with another stride (1..=`BOX_SIZE - 1`).
    pub fn with_stride(width: u16, height: u16, stride: u16, seed: u64) -> Option<Self> {
        if stride == 0 || stride >= BOX_SIZE {
            return None;
        }
        let half = BOX_SIZE / 2;
        let cy = (height / 2).checked_sub(half)?;
        let left = (width / 2).checked_sub(BOX_OFFSET_X)?.checked_sub(half)?;
        let right = (width / 2).checked_add(BOX_OFFSET_X)?.checked_sub(half)?;
        if u32::from(right) + u32::from(BOX_SIZE) > u32::from(width)
            || u32::from(cy) + u32::from(BOX_SIZE) > u32::from(height)
        {
            return None;
        }
        let mut mask = [0u8; BOX_CELLS];
        let mut rng = SplitMix64(seed);
        // Candidate positions: a pair (x, x + stride) inside the box on a row, per orientation.
        let pairs_per_row = (BOX_SIZE - stride) as u64;
        let candidates = pairs_per_row * u64::from(BOX_SIZE);
        for dir in Dir::BOTH {
            let mut placed = 0usize;
            let mut guard = 0u32;
            while placed < UNITS_PER_BOX / 2 && guard < 100_000 {
                guard += 1;
                let k = rng.below(candidates);
                let (x, y) = ((k % pairs_per_row) as u16, (k / pairs_per_row) as u16);
                let trg_x = match dir {
                    Dir::LeftToRight => x + stride,
                    Dir::RightToLeft => x,
                };
                let cell = usize::from(y) * usize::from(BOX_SIZE) + usize::from(trg_x);
                let bit = 1u8 << dir.slot();
                if let Some(m) = mask.get_mut(cell) {
                    if *m & bit == 0 {
                        *m |= bit;
                        placed += 1;
                    }
                }
            }
        }
        Some(Self {
            sensor_w: width,
            sensor_h: height,
            stride,
            origin: [(left, cy), (right, cy)],
            mask,
        })
    }

    /// Top-left corners of the two boxes.
    pub fn origins(&self) -> [(u16, u16); 2] {
        self.origin
    }
}

impl Layout for PaperBoxes {
    fn cell_count(&self) -> usize {
        2 * BOX_CELLS
    }

    fn unit_count(&self) -> usize {
        2 * self
            .mask
            .iter()
            .map(|m| m.count_ones() as usize)
            .sum::<usize>()
    }

    fn stride(&self) -> u16 {
        self.stride
    }

    fn sensor(&self) -> (u16, u16) {
        (self.sensor_w, self.sensor_h)
    }

    #[inline]
    fn cell(&self, x: u16, y: u16) -> Option<usize> {
        for (b, &(ox, oy)) in self.origin.iter().enumerate() {
            if let (Some(lx), Some(ly)) = (x.checked_sub(ox), y.checked_sub(oy)) {
                if lx < BOX_SIZE && ly < BOX_SIZE {
                    return Some(
                        b * BOX_CELLS + usize::from(ly) * usize::from(BOX_SIZE) + usize::from(lx),
                    );
                }
            }
        }
        None
    }

    #[inline]
    fn units(&self, cell: usize) -> UnitMask {
        self.mask.get(cell % BOX_CELLS).copied().unwrap_or(0)
    }

    fn pixel(&self, cell: usize) -> (u16, u16) {
        let b = usize::from(cell >= BOX_CELLS);
        let local = cell % BOX_CELLS;
        let (ox, oy) = self.origin.get(b).copied().unwrap_or((0, 0));
        let lx = (local % usize::from(BOX_SIZE)) as u16;
        let ly = (local / usize::from(BOX_SIZE)) as u16;
        (ox.saturating_add(lx), oy.saturating_add(ly))
    }
}

/// SplitMix64: a tiny seeded generator for layouts (not for anything secret).
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`), by rejection.
    fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            return 0;
        }
        let zone = u64::MAX - u64::MAX % n;
        loop {
            let v = self.next();
            if v < zone {
                return v % n;
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn dense_has_the_papers_unit_count() {
        let d = Dense::new(346, 260, 2).unwrap();
        assert_eq!(d.unit_count(), 178_880);
        assert_eq!(d.cell_count(), 346 * 260);
    }

    #[test]
    fn dense_units_have_both_pixels_on_the_sensor() {
        let d = Dense::new(10, 3, 2).unwrap();
        for c in 0..d.cell_count() {
            let (x, _) = d.pixel(c);
            let m = d.units(c);
            assert_eq!(m & 1 != 0, x >= 2, "LR unit at x={x}");
            assert_eq!(m & 2 != 0, x + 2 < 10, "RL unit at x={x}");
        }
    }

    #[test]
    fn paper_boxes_place_100_units_per_box_half_each_way() {
        let p = PaperBoxes::new(346, 260, 7).unwrap();
        assert_eq!(p.unit_count(), 200);
        let lr: u32 = p.mask.iter().map(|m| u32::from(m & 1)).sum();
        let rl: u32 = p.mask.iter().map(|m| u32::from(m >> 1 & 1)).sum();
        assert_eq!((lr, rl), (50, 50));
        // Vertically centred, 100 px either side of the centre (346/2 = 173).
        assert_eq!(p.origins(), [(63, 120), (263, 120)]);
        // Both boxes share the placement; every unit's FAC pixel is inside its box.
        for c in 0..BOX_CELLS {
            assert_eq!(p.units(c), p.units(c + BOX_CELLS));
            let (lx, m) = (c % 20, p.units(c));
            if m & 1 != 0 {
                assert!(lx >= 2);
            }
            if m & 2 != 0 {
                assert!(lx + 2 < 20);
            }
        }
        // Seeded: the same seed gives the same placement, another seed another one.
        assert_eq!(PaperBoxes::new(346, 260, 7).unwrap(), p);
        assert_ne!(PaperBoxes::new(346, 260, 8).unwrap().mask, p.mask);
        // Pixels map to cells and back.
        for c in 0..p.cell_count() {
            let (x, y) = p.pixel(c);
            assert_eq!(p.cell(x, y), Some(c));
        }
        assert_eq!(p.cell(0, 0), None);
        assert!(PaperBoxes::new(200, 100, 1).is_none());
    }
}
