//! A fast hasher for the builder's small integer keys (grid cells, vertex pairs).

use std::collections::HashMap;

/// A fast hasher for small integer keys (multiply-rotate, as in rustc's FxHasher).
#[derive(Default, Clone, Copy)]
pub(super) struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
    fn write_u32(&mut self, v: u32) {
        self.write_u64(u64::from(v));
    }
}

pub(super) type CellMap<K, V> = HashMap<K, V, std::hash::BuildHasherDefault<CellHasher>>;
