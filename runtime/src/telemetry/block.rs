//! Version 4's compressed blocks (`docs/telemetry.md`): the frames one batch of the writer
//! gathers, stored as one block frame whose CRC covers them all.
//!
//! A period changes little from the one before, but its noisy measurements fill the low bytes
//! of their numbers with noise that no compressor shrinks. What can be removed is everything
//! else, so the periods are taken out of the frame stream into a table of 52 eight-byte fields
//! per period. Each field, over the block's periods, is replaced by its residual against one of
//! three predictions (the value before, XOR-ed; the value before, subtracted; the straight line
//! through the two before, subtracted, for a quantity that moves steadily such as a wire length
//! or an encoder count), whichever leaves the fewest significant bits; the table is then stored
//! field by field, byte by byte, so that the constant high bytes form long runs. Signed
//! differences are zig-zag coded so that a small step down is a small number too.
//!
//! A block's payload:
//!
//! | bytes | what |
//! |---|---|
//! | 4 | length of the frame stream (u32) |
//! | 4 | periods in the table (u32) |
//! | 4 | length of the compressed frame stream (u32) |
//! | 52 | the prediction of each field (0: XOR, 1: difference, 2: line) |
//! | n | the frame stream, one zstd frame |
//! | rest | the table, one zstd frame (absent without periods) |
//!
//! The frame stream holds the block's frames without CRC: kind (u8), three zero bytes, payload
//! length (u32), payload. A period frame has length 0 and takes the table's next period.

use std::io;

use super::format::{FrameKind, FRAME_HEAD_BYTES, MAX_FRAME_PAYLOAD, PERIOD_BYTES};

/// zstd level of the frame stream (sessions, calibrations, surfaces): zstd's default. A relief
/// differs little from the one before it, and level 3 already finds that.
pub const STREAM_LEVEL: i32 = 3;

/// zstd level of the period table, measured on 30 s twin sessions of the box scene (the size
/// per period, and the writer thread's CPU time per second of session, which `videtd` logs as
/// `writer_cpu_s` when it closes the log): level 3 145 B and 5 ms, 9 144 B and 7 ms, 13 142 B
/// and 15 ms, 16 141 B and 19 ms, 19 141 B and 32 ms.
pub const TABLE_LEVEL: i32 = 16;

/// Largest frame stream or table a reader accepts, bytes.
pub const MAX_BLOCK_PART: usize = MAX_FRAME_PAYLOAD;

/// Bytes of a block's fixed head.
const BLOCK_HEAD_BYTES: usize = 12 + FIELDS;

/// Eight-byte fields of a period.
const FIELDS: usize = PERIOD_BYTES / 8;

/// How a field is predicted: from its own values before it in the block, or as moving by the
/// same step as a field before it in the period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Prediction {
    /// XOR with the value before.
    Xor,
    /// The difference from the value before, zig-zag coded.
    Difference,
    /// The difference from the line through the two values before, zig-zag coded.
    Line,
    /// The difference from the value before plus the step the field `0` made since the period
    /// before (an earlier field of the period), zig-zag coded: the tension read and recorded,
    /// the rendered force and the desired one.
    Along(u8),
}

/// What a field's value is predicted from.
#[derive(Debug, Clone, Copy, Default)]
struct Context {
    /// The field's value in the period before (zero before the first).
    before: u64,
    /// The field's value two periods before (zero before the second).
    before2: u64,
    /// The step of the field an [`Prediction::Along`] follows (its value at the first).
    step: u64,
}

impl Prediction {
    const OWN: [Prediction; 3] = [Prediction::Xor, Prediction::Difference, Prediction::Line];

    fn code(self) -> u8 {
        match self {
            Prediction::Xor => 0,
            Prediction::Difference => 1,
            Prediction::Line => 2,
            Prediction::Along(g) => 3 + g,
        }
    }

    /// The prediction of code `b` for field `f`: [`Prediction::Along`] an earlier field only.
    fn of_code(b: u8, f: usize) -> Option<Prediction> {
        match b {
            0..=2 => Some(Prediction::OWN[usize::from(b)]),
            _ => Some(Prediction::Along(b - 3)).filter(|_| usize::from(b - 3) < f),
        }
    }

    /// The residual of `value`.
    fn residual(self, value: u64, c: Context) -> u64 {
        match self {
            Prediction::Xor => value ^ c.before,
            Prediction::Difference => zigzag(value.wrapping_sub(c.before)),
            Prediction::Line => zigzag(
                value
                    .wrapping_sub(c.before.wrapping_mul(2))
                    .wrapping_add(c.before2),
            ),
            Prediction::Along(_) => zigzag(value.wrapping_sub(c.before).wrapping_sub(c.step)),
        }
    }

    /// The value of `residual`.
    fn value(self, residual: u64, c: Context) -> u64 {
        match self {
            Prediction::Xor => residual ^ c.before,
            Prediction::Difference => unzigzag(residual).wrapping_add(c.before),
            Prediction::Line => unzigzag(residual)
                .wrapping_add(c.before.wrapping_mul(2))
                .wrapping_sub(c.before2),
            Prediction::Along(_) => unzigzag(residual)
                .wrapping_add(c.before)
                .wrapping_add(c.step),
        }
    }
}

/// The context of field `f` in period `row` under `p`, from `columns`: the block's fields as
/// numbers, field after field, `rows` each (those of the periods before `row`, and of the
/// fields before `f` in period `row`, are all it reads).
fn context(columns: &[u64], rows: usize, row: usize, f: usize, p: Prediction) -> Context {
    let at = |row: Option<usize>, f: usize| row.map_or(0, |row| columns[f * rows + row]);
    let step = match p {
        Prediction::Along(g) => {
            let g = usize::from(g);
            at(Some(row), g).wrapping_sub(at(row.checked_sub(1), g))
        }
        _ => 0,
    };
    Context {
        before: at(row.checked_sub(1), f),
        before2: at(row.checked_sub(2), f),
        step,
    }
}

fn zigzag(v: u64) -> u64 {
    let signed = v as i64;
    ((signed << 1) ^ (signed >> 63)) as u64
}

fn unzigzag(z: u64) -> u64 {
    (z >> 1) ^ (z & 1).wrapping_neg()
}

/// The field `field` of the period `row` of a table of periods.
fn field(periods: &[u8], row: usize, field: usize) -> u64 {
    let at = row * PERIOD_BYTES + field * 8;
    u64::from_le_bytes(periods[at..at + 8].try_into().expect("8 bytes"))
}

/// The frames of one block as the writer gathers them, and the buffers it seals them with
/// (kept from block to block: the writer allocates only while its blocks grow).
pub struct BlockBuilder {
    /// The frame stream, periods as markers.
    stream: Vec<u8>,
    /// The periods' payloads, one after the other.
    periods: Vec<u8>,
    /// The table of residuals.
    table: Vec<u8>,
    /// The periods' fields as numbers, field by field, and their steps from one period to the
    /// next: what the predictions are chosen on.
    columns: Vec<u64>,
    steps: Vec<u64>,
    stream_zstd: zstd::bulk::Compressor<'static>,
    table_zstd: zstd::bulk::Compressor<'static>,
}

impl BlockBuilder {
    /// A builder with room for a block of about `bytes`.
    pub fn with_capacity(bytes: usize) -> io::Result<BlockBuilder> {
        let compressor = |level| -> io::Result<zstd::bulk::Compressor<'static>> {
            let mut c = zstd::bulk::Compressor::new(level)?;
            c.set_parameter(zstd::zstd_safe::CParameter::ChecksumFlag(true))?;
            Ok(c)
        };
        Ok(BlockBuilder {
            stream: Vec::with_capacity(bytes / 8),
            periods: Vec::with_capacity(bytes),
            table: Vec::with_capacity(bytes),
            columns: Vec::with_capacity(bytes / 8),
            steps: Vec::with_capacity(bytes / 8),
            stream_zstd: compressor(STREAM_LEVEL)?,
            table_zstd: compressor(TABLE_LEVEL)?,
        })
    }

    /// Add a frame.
    pub fn push(&mut self, kind: FrameKind, payload: &[u8]) {
        let stored = if kind == FrameKind::Period && payload.len() == PERIOD_BYTES {
            self.periods.extend_from_slice(payload);
            0
        } else {
            payload.len()
        };
        self.stream.push(kind as u8);
        self.stream.extend_from_slice(&[0; 3]);
        self.stream
            .extend_from_slice(&(stored as u32).to_le_bytes());
        self.stream.extend_from_slice(&payload[..stored]);
    }

    /// The bytes the block's frames take before compression.
    pub fn len(&self) -> usize {
        self.stream.len() + self.periods.len()
    }

    /// Drop the frames added since the last seal.
    pub fn clear(&mut self) {
        self.stream.clear();
        self.periods.clear();
    }

    /// Whether no frame was added since the last seal.
    pub fn is_empty(&self) -> bool {
        self.stream.is_empty()
    }

    /// The block's payload, to be framed as [`FrameKind::Block`]; the builder is emptied.
    pub fn seal(&mut self) -> io::Result<Vec<u8>> {
        let rows = self.periods.len() / PERIOD_BYTES;
        let predictions = self.fill_table(rows);
        let stream = self.stream_zstd.compress(&self.stream)?;
        let mut payload =
            Vec::with_capacity(BLOCK_HEAD_BYTES + stream.len() + self.table.len() / 2);
        payload.extend_from_slice(&(self.stream.len() as u32).to_le_bytes());
        payload.extend_from_slice(&(rows as u32).to_le_bytes());
        payload.extend_from_slice(&(stream.len() as u32).to_le_bytes());
        payload.extend(predictions.iter().map(|p| p.code()));
        payload.extend_from_slice(&stream);
        if rows > 0 {
            payload.extend_from_slice(&self.table_zstd.compress(&self.table)?);
        }
        self.stream.clear();
        self.periods.clear();
        Ok(payload)
    }

    /// Choose each field's prediction and write the residuals, field by field and byte by
    /// byte, into the table.
    fn fill_table(&mut self, rows: usize) -> [Prediction; FIELDS] {
        self.table.clear();
        self.table.resize(rows * PERIOD_BYTES, 0);
        self.columns.clear();
        self.columns.resize(FIELDS * rows, 0);
        self.steps.clear();
        self.steps.resize(FIELDS * rows, 0);
        for row in 0..rows {
            for f in 0..FIELDS {
                let v = field(&self.periods, row, f);
                let before = row.checked_sub(1).map_or(0, |r| field(&self.periods, r, f));
                self.columns[f * rows + row] = v;
                self.steps[f * rows + row] = v.wrapping_sub(before);
            }
        }
        let (columns, steps) = (&self.columns, &self.steps);
        let residual = |f: usize, p: Prediction, row: usize| {
            p.residual(columns[f * rows + row], context(columns, rows, row, f, p))
        };
        // The significant bits of a residual: a measure of what is left to store.
        let bits = |r: u64| u64::from(64 - r.leading_zeros());
        core::array::from_fn(|f| {
            let column = &columns[f * rows..(f + 1) * rows];
            let own_steps = &steps[f * rows..(f + 1) * rows];
            // Each prediction's bits in all, the field's own first, in one pass each.
            let xor: u64 = (0..rows)
                .map(|row| bits(column[row] ^ row.checked_sub(1).map_or(0, |r| column[r])))
                .sum();
            let difference: u64 = own_steps.iter().map(|d| bits(zigzag(*d))).sum();
            let line: u64 = own_steps
                .iter()
                .zip(std::iter::once(&0).chain(own_steps))
                .map(|(d, before)| bits(zigzag(d.wrapping_sub(*before))))
                .sum();
            let mut best = (xor, Prediction::Xor);
            for candidate in [
                (difference, Prediction::Difference),
                (line, Prediction::Line),
            ] {
                if candidate.0 < best.0 {
                    best = candidate;
                }
            }
            for g in 0..f {
                let other = &steps[g * rows..(g + 1) * rows];
                let along: u64 = own_steps
                    .iter()
                    .zip(other)
                    .map(|(d, o)| bits(zigzag(d.wrapping_sub(*o))))
                    .sum();
                if along < best.0 {
                    best = (along, Prediction::Along(g as u8));
                }
            }
            let best = best.1;
            let column = &mut self.table[f * 8 * rows..(f + 1) * 8 * rows];
            for row in 0..rows {
                for (byte, b) in residual(f, best, row).to_le_bytes().into_iter().enumerate() {
                    column[byte * rows + row] = b;
                }
            }
            best
        })
    }
}

/// A block decoded: its frames, in order.
#[derive(Default)]
pub struct DecodedBlock {
    stream: Vec<u8>,
    table: Vec<u8>,
    /// The fields decoded, field after field.
    columns: Vec<u64>,
    periods: Vec<u8>,
}

impl DecodedBlock {
    /// Decode a block frame's payload into `self` (its buffers reused); the frames are then
    /// read with [`DecodedBlock::frames`]. A damaged block is an error, never a panic.
    pub fn decode(&mut self, payload: &[u8]) -> Result<(), String> {
        let head = payload
            .get(..BLOCK_HEAD_BYTES)
            .ok_or("a block frame too short")?;
        let u32_at =
            |at: usize| u32::from_le_bytes(head[at..at + 4].try_into().expect("4 bytes")) as usize;
        let (stream_len, rows, stream_zlen) = (u32_at(0), u32_at(4), u32_at(8));
        if stream_len > MAX_BLOCK_PART || rows > MAX_BLOCK_PART / PERIOD_BYTES {
            return Err(format!(
                "a block of {stream_len} bytes of frames and {rows} periods"
            ));
        }
        let mut predictions = [Prediction::Xor; FIELDS];
        for (f, (p, b)) in predictions.iter_mut().zip(&head[12..]).enumerate() {
            *p = Prediction::of_code(*b, f)
                .ok_or(format!("a block with prediction {b} for field {f}"))?;
        }
        let body = &payload[BLOCK_HEAD_BYTES..];
        let (stream, table) = (body.get(..stream_zlen), body.get(stream_zlen..));
        let (Some(stream), Some(table)) = (stream, table) else {
            return Err("a block shorter than its frame stream".into());
        };
        let mut zstd = zstd::bulk::Decompressor::new().map_err(|e| e.to_string())?;
        let mut unpack = |packed: &[u8], out: &mut Vec<u8>, len: usize| {
            out.clear();
            if len == 0 && packed.is_empty() {
                return Ok(());
            }
            out.reserve(len);
            zstd.decompress_to_buffer(packed, out)
                .map_err(|e| format!("a block that does not decompress ({e})"))?;
            if out.len() == len {
                Ok(())
            } else {
                Err(format!(
                    "a block part of {} bytes where its head says {len}",
                    out.len()
                ))
            }
        };
        unpack(stream, &mut self.stream, stream_len)?;
        unpack(table, &mut self.table, rows * PERIOD_BYTES)?;
        self.periods.clear();
        self.periods.resize(rows * PERIOD_BYTES, 0);
        // Field by field: a field followed by another is decoded before it.
        self.columns.clear();
        self.columns.resize(FIELDS * rows, 0);
        for (f, p) in predictions.iter().enumerate() {
            let column = &self.table[f * 8 * rows..(f + 1) * 8 * rows];
            for row in 0..rows {
                let r = u64::from_le_bytes(core::array::from_fn(|byte| column[byte * rows + row]));
                self.columns[f * rows + row] = p.value(r, context(&self.columns, rows, row, f, *p));
            }
        }
        for (row, period) in self.periods.chunks_exact_mut(PERIOD_BYTES).enumerate() {
            for (f, value) in period.chunks_exact_mut(8).enumerate() {
                value.copy_from_slice(&self.columns[f * rows + row].to_le_bytes());
            }
        }
        Ok(())
    }

    /// The block's frames: kind and payload, or what is wrong with the next one (then none
    /// after it).
    pub fn frames(&self) -> BlockFrames<'_> {
        BlockFrames {
            stream: &self.stream,
            periods: &self.periods,
            at: 0,
            row: 0,
        }
    }
}

/// The frames of a [`DecodedBlock`].
pub struct BlockFrames<'a> {
    stream: &'a [u8],
    periods: &'a [u8],
    at: usize,
    row: usize,
}

impl<'a> BlockFrames<'a> {
    fn fail(&mut self, what: &str) -> Option<Result<(FrameKind, &'a [u8]), String>> {
        self.at = self.stream.len();
        self.row = self.periods.len() / PERIOD_BYTES;
        Some(Err(what.to_string()))
    }
}

impl<'a> Iterator for BlockFrames<'a> {
    type Item = Result<(FrameKind, &'a [u8]), String>;

    fn next(&mut self) -> Option<Self::Item> {
        let rest = &self.stream[self.at..];
        if rest.is_empty() {
            if self.row * PERIOD_BYTES != self.periods.len() {
                return self.fail("a block with more periods than period frames");
            }
            return None;
        }
        let Some(head) = rest.get(..FRAME_HEAD_BYTES) else {
            return self.fail("a block with an incomplete frame");
        };
        let len = u32::from_le_bytes(head[4..8].try_into().expect("4 bytes")) as usize;
        let kind = FrameKind::from_byte(head[0]).filter(|k| *k != FrameKind::Block);
        let Some(kind) = kind.filter(|_| head[1..4] == [0, 0, 0]) else {
            return self.fail(&format!(
                "a corrupt frame head in a block (kind {})",
                head[0]
            ));
        };
        let Some(payload) = rest.get(FRAME_HEAD_BYTES..FRAME_HEAD_BYTES + len) else {
            return self.fail("a block with an incomplete frame");
        };
        self.at += FRAME_HEAD_BYTES + len;
        if kind == FrameKind::Period && len == 0 {
            let at = self.row * PERIOD_BYTES;
            let Some(row) = self.periods.get(at..at + PERIOD_BYTES) else {
                return self.fail("a block with more period frames than periods");
            };
            self.row += 1;
            return Some(Ok((kind, row)));
        }
        Some(Ok((kind, payload)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A period whose fields move as a session's do: steady lines, noisy values, constants.
    fn period(i: u64) -> [u8; PERIOD_BYTES] {
        let mut p = [0u8; PERIOD_BYTES];
        let mut noise = i.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        for (f, chunk) in p.chunks_exact_mut(8).enumerate() {
            noise ^= noise << 13;
            noise ^= noise >> 7;
            noise ^= noise << 17;
            let v = match f % 4 {
                0 => i,
                1 => (0.3 + 1e-5 * i as f64).to_bits(),
                2 => (0.5 + (noise % 1000) as f64 * 1e-6).to_bits(),
                _ => 7,
            };
            chunk.copy_from_slice(&v.to_le_bytes());
        }
        p
    }

    fn decode(payload: &[u8]) -> Result<Vec<(FrameKind, Vec<u8>)>, String> {
        let mut d = DecodedBlock::default();
        d.decode(payload)?;
        d.frames()
            .map(|f| f.map(|(k, p)| (k, p.to_vec())))
            .collect()
    }

    #[test]
    fn a_block_gives_back_its_frames_in_order() {
        let mut b = BlockBuilder::with_capacity(4096).unwrap();
        let want: Vec<(FrameKind, Vec<u8>)> = vec![
            (FrameKind::Session, b"name = 'x'".to_vec()),
            (FrameKind::Period, period(1).to_vec()),
            (FrameKind::Period, period(2).to_vec()),
            (FrameKind::SurfaceLost, 7u64.to_le_bytes().to_vec()),
            (FrameKind::Period, period(3).to_vec()),
            (FrameKind::End, Vec::new()),
        ];
        for (k, p) in &want {
            b.push(*k, p);
        }
        let payload = b.seal().unwrap();
        assert!(b.is_empty());
        assert_eq!(decode(&payload).unwrap(), want);
        // The builder starts the next block empty.
        b.push(FrameKind::Period, &period(4));
        assert_eq!(
            decode(&b.seal().unwrap()).unwrap(),
            vec![(FrameKind::Period, period(4).to_vec())]
        );
    }

    #[test]
    fn every_prediction_gives_back_every_value() {
        let edges = [
            0,
            1,
            2,
            u64::MAX,
            u64::MAX - 1,
            1 << 63,
            (1 << 63) - 1,
            0x5555,
        ];
        for p in Prediction::OWN.into_iter().chain([Prediction::Along(0)]) {
            for v in edges {
                for before in edges {
                    for before2 in edges {
                        for step in [0, 1, u64::MAX, 1 << 63] {
                            let c = Context {
                                before,
                                before2,
                                step,
                            };
                            let r = p.residual(v, c);
                            assert_eq!(p.value(r, c), v, "{p:?} {v} {c:?}");
                        }
                    }
                }
            }
        }
        // Small steps either way are small residuals.
        let c = |before, before2, step| Context {
            before,
            before2,
            step,
        };
        assert_eq!(Prediction::Difference.residual(5, c(6, 0, 0)), 1);
        assert_eq!(Prediction::Difference.residual(7, c(6, 0, 0)), 2);
        assert_eq!(Prediction::Line.residual(30, c(20, 10, 0)), 0);
        assert_eq!(Prediction::Along(1).residual(30, c(20, 0, 10)), 0);
        // A field follows only an earlier one.
        assert_eq!(Prediction::of_code(3 + 4, 5), Some(Prediction::Along(4)));
        assert_eq!(Prediction::of_code(3 + 5, 5), None);
    }

    #[test]
    fn a_field_that_moves_with_another_is_stored_along_it() {
        let mut b = BlockBuilder::with_capacity(1 << 16).unwrap();
        let mut noise = 0x2545_f491_4f6c_dd1du64;
        let mut rows = Vec::new();
        for _ in 0..100 {
            noise ^= noise << 13;
            noise ^= noise >> 7;
            noise ^= noise << 17;
            let mut p = [0u8; PERIOD_BYTES];
            // Field 3 is noise, field 7 the same noise and a constant offset.
            p[24..32].copy_from_slice(&noise.to_le_bytes());
            p[56..64].copy_from_slice(&noise.wrapping_add(12345).to_le_bytes());
            b.push(FrameKind::Period, &p);
            rows.push(p);
        }
        let predictions = b.fill_table(100);
        assert_eq!(predictions[7], Prediction::Along(3));
        let payload = b.seal().unwrap();
        let frames = decode(&payload).unwrap();
        assert_eq!(frames.len(), 100);
        for (got, want) in frames.iter().zip(&rows) {
            assert_eq!(got.1, want.to_vec());
        }
    }

    #[test]
    fn a_damaged_block_is_an_error_not_a_panic() {
        let mut b = BlockBuilder::with_capacity(1 << 16).unwrap();
        b.push(FrameKind::Session, b"session");
        for i in 0..50 {
            b.push(FrameKind::Period, &period(i));
        }
        let payload = b.seal().unwrap();
        assert_eq!(decode(&payload).unwrap().len(), 51);
        for cut in [
            0,
            3,
            BLOCK_HEAD_BYTES,
            BLOCK_HEAD_BYTES + 5,
            payload.len() / 2,
            payload.len() - 1,
        ] {
            assert!(decode(&payload[..cut]).is_err(), "cut at {cut}");
        }
        // Any flipped byte: never a panic. In the compressed parts, either an error (zstd's
        // checksum) or, where zstd ignores the bit, the same frames. (The block frame's CRC
        // finds any flipped byte before this.)
        let whole = decode(&payload).unwrap();
        for at in 0..payload.len() {
            let mut flipped = payload.clone();
            flipped[at] ^= 0x40;
            let read = decode(&flipped);
            if at >= BLOCK_HEAD_BYTES {
                assert!(
                    read.is_err() || read == Ok(whole.clone()),
                    "flipped at {at}"
                );
            }
        }
    }

    #[test]
    fn a_sessions_periods_compress_several_times() {
        let mut b = BlockBuilder::with_capacity(1 << 20).unwrap();
        for i in 0..1000 {
            b.push(FrameKind::Period, &period(i));
        }
        let raw = b.len();
        let payload = b.seal().unwrap();
        // A quarter of the fields are noise of about 10 bits, the rest predictable.
        assert!(
            payload.len() * 4 < raw,
            "{raw} bytes stored in {}",
            payload.len()
        );
    }
}
