//! Turning fuzzer bytes into numbers: a cursor that yields bytes and f64s,
//! with a tag byte that favours the values where numerics break (NaN, ±Inf,
//! 0, ±1e±300, subnormals) over raw bit patterns. Exhausted input yields 0.
#![allow(dead_code)]

pub struct Bytes<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Bytes<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        Bytes { data, pos: 0 }
    }

    pub fn u8(&mut self) -> u8 {
        let b = self.data.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        b
    }

    pub fn usize_below(&mut self, n: usize) -> usize {
        let v = u16::from_le_bytes([self.u8(), self.u8()]) as usize;
        v % n.max(1)
    }

    pub fn bits(&mut self) -> f64 {
        let mut b = [0u8; 8];
        for x in b.iter_mut() {
            *x = self.u8();
        }
        f64::from_le_bytes(b)
    }

    /// Any f64, special values favoured.
    pub fn f64(&mut self) -> f64 {
        match self.u8() {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => f64::NEG_INFINITY,
            3 => 0.0,
            4 => 1e300,
            5 => 1e-300,
            6 => -1e300,
            7 => 5e-324,
            8 => 1.0,
            9 => -0.0,
            10..=127 => self.bits(),
            t => self.unit() * (t as f64 - 191.0) / 16.0, // moderate values, about ±4
        }
    }

    /// A value in [0, 1) from two bytes.
    pub fn unit(&mut self) -> f64 {
        u16::from_le_bytes([self.u8(), self.u8()]) as f64 / 65536.0
    }

    /// A finite value in (lo, hi) (log-uniform when lo > 0).
    pub fn in_range(&mut self, lo: f64, hi: f64) -> f64 {
        let u = (self.unit() + 1e-6) / (1.0 + 2e-6);
        if lo > 0.0 {
            (lo.ln() + u * (hi.ln() - lo.ln())).exp()
        } else {
            lo + u * (hi - lo)
        }
    }

    pub fn is_empty(&self) -> bool {
        self.pos >= self.data.len()
    }
}
