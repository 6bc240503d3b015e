//! The EXR file of a render written while it is traced ([`crate::render::stream`]): the same file
//! [`crate::output::exr::write_exr_with`] writes from a whole [`crate::render::Frame`], byte for
//! byte, made from bands of rows.
//!
//! A single-part scanline EXR is: magic number and version, the header, the offset table (one
//! `u64` file position per block of scanlines), then the blocks. The header and a zeroed table
//! are written when the file is created; each band is cut into blocks of the codec's lines per
//! block (1 uncompressed, RLE and ZIPS; 16 ZIP; 32 PIZ — bands are aligned to them) and
//! compressed by the thread that traced it ([`BandSink::prepare`]); the blocks are appended in
//! increasing `y` order ([`BandSink::write`]), their positions noted; [`ExrStream::finish`]
//! fills the table in, sorts the header's attributes (as the whole-frame writer does) and
//! renames the file into place ([`crate::output::atomic`]: until then the destination keeps its
//! old contents, and a file dropped unfinished is deleted).
//!
//! The header is the one the `exr` crate infers for the whole-frame image (the same channel
//! list, sorted by name, the same attributes); compressed blocks are made with the crate's own
//! `UncompressedBlock::compress_to_chunk` and written with its `Chunk::write`. Uncompressed
//! blocks (the default) are written here, with the same bytes (`y`, byte count, samples
//! little-endian): the samples go from the band straight into the encoded band, and that
//! straight to the file, where the crate's path copied them three times.

use crate::output::atomic::{start_writeback, AtomicFile};

/// Bytes written between two requests to start writing them to disk.
const WRITEBACK_BYTES: u64 = 16 << 20;

/// The output buffer's size: bands of at least this many bytes are written without it.
const DIRECT_WRITE_BYTES: usize = 64 << 10;
use crate::output::exr::{flat_image, frame_channels, sort_header_attributes, ExrCompression, ExrHeader};
use crate::render::stream::BandSink;
use crate::render::FrameLayout;
use anyhow::{bail, Context, Result};
use exr::block::{BlockIndex, UncompressedBlock};
use exr::meta::header::Header;
use exr::meta::{magic_number, Headers, MetaData};
use exr::prelude::*;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

/// An EXR file being written band by band; see the module docs.
pub struct ExrStream {
    path: PathBuf,
    headers: Headers,
    /// For each channel of the file (in the file's order, by name), its offset within an
    /// interleaved pixel of the bands.
    sources: Vec<usize>,
    /// Channels per interleaved pixel.
    stride: usize,
    width: usize,
    window_y0: u32,
    lines_per_block: usize,
    /// The codec stores samples as they are: blocks are encoded here, without the crate.
    uncompressed: bool,
    /// The data window's top row: an uncompressed block's `y` is it plus the block's row.
    layer_y: i32,
    block_count: usize,
    /// File position of the offset table.
    table_start: u64,
    state: Mutex<Written>,
    /// Written bands' byte buffers, for the next bands to encode into ([`BandSink::prepare`]).
    spare: Mutex<Vec<Vec<u8>>>,
}

/// What has been written so far.
struct Written {
    file: AtomicFile,
    /// A second handle on the temporary file, buffered.
    out: BufWriter<File>,
    /// File position after the last byte written.
    position: u64,
    /// File position up to which the bytes are on their way to disk ([`start_writeback`]).
    writeback: u64,
    /// File position of each block written, in increasing `y`.
    offsets: Vec<u64>,
}

impl ExrStream {
    /// Creates the temporary file beside `path` and writes the header of a frame of `layout`
    /// and a zeroed offset table.
    ///
    /// # Errors
    /// The header is invalid or the file cannot be created or written.
    pub fn create(path: &Path, layout: &FrameLayout, header: &ExrHeader, compression: ExrCompression) -> Result<Self> {
        let channels = frame_channels(layout);
        let image = flat_image(layout, vec![Vec::new(); channels.len()], header, compression);
        let headers = image.write().infer_meta_data();
        let requirements =
            MetaData::validate(&headers, true).with_context(|| format!("the header of {}", path.display()))?;
        let sources = headers[0]
            .channels
            .list
            .iter()
            .map(|c| {
                channels
                    .iter()
                    .find(|(_, _, name, _)| c.name == **name)
                    .map(|(_, _, _, offset)| *offset)
                    .expect("the file's channels are the frame's")
            })
            .collect();
        let mut head = Vec::new();
        magic_number::write(&mut head)?;
        requirements.write(&mut head)?;
        Header::write_all(&headers, &mut head, requirements.is_multilayer())?;
        let table_start = head.len() as u64;
        let block_count = headers[0].chunk_count;
        head.resize(head.len() + block_count * 8, 0);

        let mut file = AtomicFile::create(path)?;
        let handle = file
            .file()
            .try_clone()
            .with_context(|| format!("opening {}", path.display()))?;
        // a band larger than the buffer goes straight to the file (`BufWriter::write_all`),
        // without a copy; the header and a small render's bands are gathered
        let mut out = BufWriter::with_capacity(DIRECT_WRITE_BYTES, handle);
        out.write_all(&head)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            lines_per_block: compression.codec().scan_lines_per_block(),
            uncompressed: compression.codec() == Compression::Uncompressed,
            layer_y: headers[0].own_attributes.layer_position.y(),
            headers,
            sources,
            stride: layout.channel_count(),
            width: layout.window.width() as usize,
            window_y0: layout.window.y0,
            block_count,
            table_start,
            spare: Mutex::new(Vec::new()),
            state: Mutex::new(Written {
                file,
                out,
                position: head.len() as u64,
                writeback: 0,
                offsets: Vec::with_capacity(block_count),
            }),
        })
    }

    /// Writes `rows`' samples into `out` (four bytes a sample, exactly) in the file's order: per
    /// row, each channel's samples along the row (`row[x·stride + source]` for pixel `x`),
    /// little-endian.
    fn gather(&self, rows: &[f32], out: &mut [u8]) {
        // the AOV render's (Depth, Normal, Alpha) and the default outputs' (beauty, A, Z, N)
        // strides made constants in copies of their own (mesh4's default render: 3.44 -> 2.56
        // ms of CPU)
        match self.stride {
            5 => self.gather_strided(5, rows, out),
            8 => self.gather_strided(8, rows, out),
            stride => self.gather_strided(stride, rows, out),
        }
    }

    /// [`ExrStream::gather`] for `stride` samples a pixel.
    #[inline(always)]
    fn gather_strided(&self, stride: usize, rows: &[f32], out: &mut [u8]) {
        let width = self.width;
        match bytemuck::try_cast_slice_mut::<u8, u32>(out) {
            // a channel at a time, its run filled from the row's pixels as 32-bit words (a
            // sample's little-endian bytes are its bits' word here; the row, a few tens of
            // kilobytes, stays in cache across the channels): quadrics' AOV render 2.67 ->
            // 1.30 ms of CPU against the bytes a pixel at a time
            Ok(words) if cfg!(target_endian = "little") => {
                for (row, out) in rows
                    .chunks_exact(width * stride)
                    .zip(words.chunks_exact_mut(width * stride))
                {
                    for (run, &source) in out.chunks_exact_mut(width).zip(&self.sources) {
                        for (word, pixel) in run.iter_mut().zip(row.chunks_exact(stride)) {
                            *word = pixel[source].to_bits();
                        }
                    }
                }
            }
            // `out` not aligned for words (or a big-endian machine): byte by byte
            _ => {
                for (row, out) in rows
                    .chunks_exact(width * stride)
                    .zip(out.chunks_exact_mut(width * stride * 4))
                {
                    for (run, &source) in out.chunks_exact_mut(width * 4).zip(&self.sources) {
                        for (bytes, pixel) in run.chunks_exact_mut(4).zip(row.chunks_exact(stride)) {
                            bytes.copy_from_slice(&pixel[source].to_le_bytes());
                        }
                    }
                }
            }
        }
    }

    /// Fills in the offset table, sorts the header's attributes and renames the file into place.
    ///
    /// # Errors
    /// Not every block was written, or a file operation fails (the destination is then
    /// untouched).
    pub fn finish(self) -> Result<()> {
        let Written {
            mut file,
            mut out,
            offsets,
            ..
        } = self.state.into_inner().unwrap_or_else(PoisonError::into_inner);
        if offsets.len() != self.block_count {
            bail!(
                "{}: only {} of {} blocks were written",
                self.path.display(),
                offsets.len(),
                self.block_count
            );
        }
        let table: Vec<u8> = offsets.iter().flat_map(|o| o.to_le_bytes()).collect();
        out.seek(SeekFrom::Start(self.table_start))
            .and_then(|_| out.write_all(&table))
            .and_then(|()| out.flush())
            .with_context(|| format!("writing {}", self.path.display()))?;
        drop(out);
        sort_header_attributes(file.file())
            .with_context(|| format!("writing the header of {}", self.path.display()))?;
        file.commit()
    }
}

impl BandSink for ExrStream {
    fn row_alignment(&self) -> u32 {
        self.lines_per_block as u32
    }

    /// The band's blocks, compressed and encoded as the file stores them (`y`, byte count,
    /// bytes): per line, each channel's samples along the line.
    fn prepare(&self, first_row: u32, rows: &[f32]) -> Result<Vec<u8>> {
        let row_len = self.width * self.stride;
        let lines = rows.len() / row_len.max(1);
        // a written band's bytes, whose pages are mapped (fresh memory is faulted in and zeroed
        // page by page); uncompressed, a band's bytes have one length for every band but the
        // last, so `resize` writes nothing and every byte is overwritten below
        let mut encoded = self
            .spare
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .pop()
            .unwrap_or_default();
        if self.uncompressed {
            encoded.resize(rows.len() * 4 + 8 * lines.div_ceil(self.lines_per_block), 0);
        } else {
            encoded.clear();
        }
        let mut at = 0;
        let mut line = 0;
        while line < lines {
            let block_lines = self.lines_per_block.min(lines - line);
            let block_rows = &rows[line * row_len..(line + block_lines) * row_len];
            let position = (first_row - self.window_y0) as usize + line;
            if self.uncompressed {
                // what `compress_to_chunk` and `Chunk::write` make of an uncompressed block:
                // `y` (the data window's top plus the block's row), the byte count, then the
                // samples as they are, little-endian; gathered straight into the band's bytes
                let y = i32::try_from(position)
                    .ok()
                    .and_then(|p| p.checked_add(self.layer_y))
                    .with_context(|| format!("{}: row {position} is past the format's limit", self.path.display()))?;
                let bytes = i32::try_from(block_rows.len() * 4)
                    .with_context(|| format!("{}: a line of more than 2 GiB", self.path.display()))?;
                encoded[at..at + 4].copy_from_slice(&y.to_le_bytes());
                encoded[at + 4..at + 8].copy_from_slice(&bytes.to_le_bytes());
                let end = at + 8 + block_rows.len() * 4;
                self.gather(block_rows, &mut encoded[at + 8..end]);
                at = end;
            } else {
                let mut data = vec![0; block_rows.len() * 4];
                self.gather(block_rows, &mut data);
                let block = UncompressedBlock {
                    index: BlockIndex {
                        layer: 0,
                        pixel_position: Vec2(0, position),
                        pixel_size: Vec2(self.width, block_lines),
                        level: Vec2(0, 0),
                    },
                    data,
                };
                block
                    .compress_to_chunk(&self.headers)
                    .and_then(|chunk| chunk.write(&mut encoded, 1))
                    .with_context(|| format!("encoding {}", self.path.display()))?;
            }
            line += block_lines;
        }
        debug_assert!(
            !self.uncompressed || at == encoded.len(),
            "every byte of the band written"
        );
        Ok(encoded)
    }

    fn write(&self, _first_row: u32, _rows: &[f32], prepared: Vec<u8>) -> Result<()> {
        let mut written = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        // each block: y (i32), byte count (i32), bytes
        let mut at = 0;
        while at + 8 <= prepared.len() {
            let position = written.position + at as u64;
            written.offsets.push(position);
            let size = i32::from_le_bytes(prepared[at + 4..at + 8].try_into().expect("four bytes"));
            at += 8 + usize::try_from(size).context("negative block size")?;
        }
        written
            .out
            .write_all(&prepared)
            .with_context(|| format!("writing {}", self.path.display()))?;
        written.position += prepared.len() as u64;
        if written.position - written.writeback >= WRITEBACK_BYTES {
            written
                .out
                .flush()
                .with_context(|| format!("writing {}", self.path.display()))?;
            let (from, to) = (written.writeback, written.position);
            start_writeback(written.out.get_ref(), from, to - from);
            written.writeback = to;
        }
        drop(written);
        // the bytes are in the file (or its buffer): the vector serves a later band
        self.spare.lock().unwrap_or_else(PoisonError::into_inner).push(prepared);
        Ok(())
    }
}
