//! Stage 2, the per-frame plan: a fixed map from pool tiles to small values (how many cells read a tile,
//! which slot holds it), so that the detail pool finds a tile in O(1) instead of scanning a thousand
//! slots per cell per frame. Open addressing with linear probing and backward-shift removal (no
//! tombstones); allocated once, never grown: a full map refuses an insert.

use crate::plan::detail::TileKey;

/// A map from [`TileKey`] to `u32` with room for `capacity` keys (its table is twice that, rounded up to
/// a power of two).
#[derive(Clone, Debug)]
pub struct KeyMap {
    table: Box<[Option<(TileKey, u32)>]>,
    len: usize,
    capacity: usize,
}

impl KeyMap {
    /// An empty map for up to `capacity` keys.
    pub fn new(capacity: usize) -> Self {
        let slots = (2 * capacity.max(1)).next_power_of_two();
        Self {
            table: vec![None; slots].into_boxed_slice(),
            len: 0,
            capacity,
        }
    }

    fn home(&self, k: &TileKey) -> usize {
        #[expect(clippy::cast_sign_loss, reason = "hash mixing: only the bits matter")]
        let h = crate::plan::slot_hash(&[u64::from(k.level), k.cx as u64, k.cy as u64]);
        usize::try_from(h).unwrap_or(0) & (self.table.len() - 1)
    }

    /// Keys held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it holds no key.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Forgets every key.
    pub fn clear(&mut self) {
        self.table.fill(None);
        self.len = 0;
    }

    /// The index of `k`'s entry, if held.
    fn find(&self, k: &TileKey) -> Option<usize> {
        let mask = self.table.len() - 1;
        let mut i = self.home(k);
        while let Some((key, _)) = &self.table[i] {
            if key == k {
                return Some(i);
            }
            i = (i + 1) & mask;
        }
        None
    }

    /// `k`'s value, if held.
    pub fn get(&self, k: &TileKey) -> Option<u32> {
        self.find(k).and_then(|i| self.table[i].map(|(_, v)| v))
    }

    /// Sets `k`'s value; false (nothing changed) when `k` is new and the map is full.
    pub fn insert(&mut self, k: TileKey, v: u32) -> bool {
        if let Some(i) = self.find(&k) {
            self.table[i] = Some((k, v));
            return true;
        }
        if self.len >= self.capacity {
            return false;
        }
        let mask = self.table.len() - 1;
        let mut i = self.home(&k);
        while self.table[i].is_some() {
            i = (i + 1) & mask;
        }
        self.table[i] = Some((k, v));
        self.len += 1;
        true
    }

    /// Removes `k` (and returns its value), shifting later entries of its run back so that no probe
    /// sequence breaks.
    pub fn remove(&mut self, k: &TileKey) -> Option<u32> {
        let mut i = self.find(k)?;
        let v = self.table[i].map(|(_, v)| v);
        let mask = self.table.len() - 1;
        self.table[i] = None;
        self.len -= 1;
        let mut j = (i + 1) & mask;
        while let Some((key, val)) = self.table[j] {
            let home = self.home(&key);
            // Move the entry back to the hole when its home is not in the (cyclic) range (i, j].
            let in_range = if i <= j {
                i < home && home <= j
            } else {
                i < home || home <= j
            };
            if !in_range {
                self.table[i] = Some((key, val));
                self.table[j] = None;
                i = j;
            }
            j = (j + 1) & mask;
        }
        v
    }

    /// Counts one more taker of `k`; false when `k` is new and the map is full.
    pub fn count_in(&mut self, k: TileKey) -> bool {
        let n = self.get(&k).unwrap_or(0);
        self.insert(k, n + 1)
    }

    /// Counts one taker of `k` fewer, removing it at none.
    pub fn count_out(&mut self, k: &TileKey) {
        match self.get(k) {
            Some(n) if n > 1 => {
                self.insert(*k, n - 1);
            }
            Some(_) => {
                self.remove(k);
            }
            None => {}
        }
    }

    /// Every (key, value), in table order (deterministic for a given history of inserts and removals).
    pub fn iter(&self) -> impl Iterator<Item = (TileKey, u32)> + '_ {
        self.table.iter().flatten().copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inserts_counts_and_removes_like_a_map() {
        let mut m = KeyMap::new(64);
        let mut model = std::collections::HashMap::new();
        let mut x = 7u64;
        for step in 0..5000 {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let k = TileKey {
                level: (x >> 60) as u32 % 3,
                cx: (x >> 40) as i64 % 9 - 4,
                cy: (x >> 20) as i64 % 9 - 4,
            };
            if x.is_multiple_of(3) {
                m.count_out(&k);
                if let Some(n) = model.get_mut(&k) {
                    *n -= 1;
                    if *n == 0 {
                        model.remove(&k);
                    }
                }
            } else if m.count_in(k) {
                *model.entry(k).or_insert(0) += 1;
            } else {
                assert!(!model.contains_key(&k) && model.len() >= 64, "step {step}");
            }
            assert_eq!(m.len(), model.len(), "step {step}");
            for (k, n) in &model {
                assert_eq!(m.get(k), Some(*n), "step {step}");
            }
        }
    }
}
