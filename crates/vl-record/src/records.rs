//! MCAP's records, read from bytes that may be damaged or hostile: a
//! Host killed mid-write, a disk error, a file someone crafted. The `mcap`
//! crate writes our files, but its reader trusts what a file declares (it
//! allocates a chunk's declared size, slices by declared lengths), and a
//! one-byte change made it panic or abort; here every length is checked
//! against the bytes there before anything is sliced or allocated, and a
//! chunk is decompressed only to a bounded size.
//!
//! Only the records a recording is read back from are parsed (schemas,
//! channels, messages, attachments, metadata, chunks, the footer); the
//! summary's indexes and statistics are skipped.

use std::collections::BTreeMap;

use thiserror::Error;

/// The largest chunk decompressed: ours close at a second or at the
/// writer's chunk size, far below.
pub(crate) const MAX_CHUNK_BYTES: u64 = 64 << 20;
/// The most a chunk may grow when decompressed: recordings (JSON, JPEG)
/// compress a few times at most; a chunk of zeros a file declares as its
/// content is a bomb, not a run.
pub(crate) const MAX_RATIO: u64 = 200;

/// Where and why reading stopped.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum Damage {
    #[error("a record at byte {at} runs past the end ({needs} bytes needed, {left} left)")]
    Truncated { at: usize, needs: u64, left: usize },
    #[error("a {what} at byte {at} is malformed")]
    Malformed { what: &'static str, at: usize },
    #[error(
        "a chunk at byte {at} declares {declared} bytes from {compressed}: over the {MAX_CHUNK_BYTES}-byte or {MAX_RATIO}× limit"
    )]
    ChunkTooLarge {
        at: usize,
        declared: u64,
        compressed: u64,
    },
    #[error("a chunk at byte {at} is compressed with \"{0}\", which vl does not read", .compression)]
    Compression { at: usize, compression: String },
    #[error("a chunk at byte {at} does not decompress to what it declares: {why}")]
    Decompress { at: usize, why: String },
    #[error("a chunk at byte {at} fails its checksum")]
    Checksum { at: usize },
}

impl Damage {
    /// Whether the records after this one may still be read: a chunk that
    /// fails to decompress or its checksum was framed whole (its length
    /// held), so only its own second of the run is lost.
    pub fn spares_the_rest(&self) -> bool {
        matches!(
            self,
            Damage::ChunkTooLarge { .. }
                | Damage::Compression { .. }
                | Damage::Decompress { .. }
                | Damage::Checksum { .. }
        )
    }
}

/// One record this reader understands.
#[derive(Debug, PartialEq)]
pub(crate) enum Record<'a> {
    Schema {
        id: u16,
        name: String,
        encoding: String,
        data: &'a [u8],
    },
    Channel {
        id: u16,
        schema_id: u16,
        topic: String,
        message_encoding: String,
    },
    Message {
        channel_id: u16,
        log_ns: u64,
        publish_ns: u64,
        data: &'a [u8],
    },
    Attachment {
        name: String,
        data: &'a [u8],
    },
    Metadata(BTreeMap<String, String>),
    /// A chunk's records, decompressed.
    Chunk(Vec<u8>),
    Footer,
    /// Any other record: skipped.
    Other,
}

mod op {
    pub(super) const FOOTER: u8 = 0x02;
    pub(super) const SCHEMA: u8 = 0x03;
    pub(super) const CHANNEL: u8 = 0x04;
    pub(super) const MESSAGE: u8 = 0x05;
    pub(super) const CHUNK: u8 = 0x06;
    pub(super) const ATTACHMENT: u8 = 0x09;
    pub(super) const METADATA: u8 = 0x0C;
}

/// The records in `bytes` (a file after its magic, or a chunk's content),
/// one after another, up to the end or the first damage that leaves the
/// rest unframed (a damaged chunk is an error, and reading goes on). `base` is where
/// `bytes` begin in the file, for the errors.
pub(crate) fn records(
    bytes: &[u8],
    base: usize,
) -> impl Iterator<Item = Result<Record<'_>, Damage>> {
    let mut at = 0;
    let mut stopped = false;
    std::iter::from_fn(move || {
        if stopped || at >= bytes.len() {
            return None;
        }
        let mut fields = Fields::new(&bytes[at..], base + at);
        let next = fields.u8().and_then(|opcode| {
            let length = fields.u64()?;
            let body = fields.take(length)?;
            at += 9 + body.len();
            parse(opcode, body, base + at - body.len())
        });
        stopped = match &next {
            Ok(record) => *record == Record::Footer,
            Err(damage) => !damage.spares_the_rest(),
        };
        Some(next)
    })
}

/// A record's body, as its opcode says.
fn parse(opcode: u8, body: &[u8], at: usize) -> Result<Record<'_>, Damage> {
    let mut f = Fields::new(body, at);
    let record = match opcode {
        op::SCHEMA => Record::Schema {
            id: f.u16()?,
            name: f.string()?,
            encoding: f.string()?,
            data: f.bytes32()?,
        },
        op::CHANNEL => {
            let record = Record::Channel {
                id: f.u16()?,
                schema_id: f.u16()?,
                topic: f.string()?,
                message_encoding: f.string()?,
            };
            f.map()?;
            record
        }
        op::MESSAGE => {
            let channel_id = f.u16()?;
            f.u32()?;
            Record::Message {
                channel_id,
                log_ns: f.u64()?,
                publish_ns: f.u64()?,
                data: f.rest(),
            }
        }
        op::ATTACHMENT => {
            f.u64()?;
            f.u64()?;
            let name = f.string()?;
            f.string()?;
            let data = f.bytes64()?;
            f.u32()?;
            Record::Attachment { name, data }
        }
        op::METADATA => {
            f.string()?;
            Record::Metadata(f.map()?)
        }
        op::CHUNK => Record::Chunk(chunk(&mut f, at)?),
        op::FOOTER => Record::Footer,
        _ => Record::Other,
    };
    Ok(record)
}

/// A chunk's records, decompressed as far as the limits allow.
fn chunk(f: &mut Fields<'_>, at: usize) -> Result<Vec<u8>, Damage> {
    f.u64()?;
    f.u64()?;
    let declared = f.u64()?;
    let crc = f.u32()?;
    let compression = f.string()?;
    let compressed = f.bytes64()?;
    let size = compressed.len() as u64;
    if declared > MAX_CHUNK_BYTES || declared > size.saturating_mul(MAX_RATIO).max(4096) {
        return Err(Damage::ChunkTooLarge {
            at,
            declared,
            compressed: size,
        });
    }
    let content = match compression.as_str() {
        "" => compressed.to_vec(),
        // The capacity is the declared size: zstd stops there, however
        // much more the data would make.
        "zstd" => zstd::bulk::decompress(compressed, declared as usize).map_err(|e| {
            Damage::Decompress {
                at,
                why: e.to_string(),
            }
        })?,
        _ => return Err(Damage::Compression { at, compression }),
    };
    if content.len() as u64 != declared {
        return Err(Damage::Decompress {
            at,
            why: format!("{} bytes, not {declared}", content.len()),
        });
    }
    if crc != 0 && crc32fast::hash(&content) != crc {
        return Err(Damage::Checksum { at });
    }
    Ok(content)
}

/// Little-endian fields read off a record, each checked against what is left.
struct Fields<'a> {
    bytes: &'a [u8],
    /// Where `bytes` begin in the file.
    at: usize,
}

impl<'a> Fields<'a> {
    fn new(bytes: &'a [u8], at: usize) -> Fields<'a> {
        Fields { bytes, at }
    }

    fn take(&mut self, n: u64) -> Result<&'a [u8], Damage> {
        if n > self.bytes.len() as u64 {
            return Err(Damage::Truncated {
                at: self.at,
                needs: n,
                left: self.bytes.len(),
            });
        }
        let (taken, rest) = self.bytes.split_at(n as usize);
        self.bytes = rest;
        self.at += taken.len();
        Ok(taken)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], Damage> {
        let taken = self.take(N as u64)?;
        Ok(taken.try_into().unwrap_or([0; N]))
    }

    fn u8(&mut self) -> Result<u8, Damage> {
        Ok(self.array::<1>()?[0])
    }

    fn u16(&mut self) -> Result<u16, Damage> {
        self.array().map(u16::from_le_bytes)
    }

    fn u32(&mut self) -> Result<u32, Damage> {
        self.array().map(u32::from_le_bytes)
    }

    fn u64(&mut self) -> Result<u64, Damage> {
        self.array().map(u64::from_le_bytes)
    }

    fn bytes32(&mut self) -> Result<&'a [u8], Damage> {
        let n = self.u32()?;
        self.take(u64::from(n))
    }

    fn bytes64(&mut self) -> Result<&'a [u8], Damage> {
        let n = self.u64()?;
        self.take(n)
    }

    fn string(&mut self) -> Result<String, Damage> {
        let at = self.at;
        let bytes = self.bytes32()?;
        String::from_utf8(bytes.to_vec()).map_err(|_| Damage::Malformed { what: "string", at })
    }

    /// A map of strings: its length in bytes, then key and value pairs.
    fn map(&mut self) -> Result<BTreeMap<String, String>, Damage> {
        let mut pairs = Fields::new(self.bytes32()?, self.at);
        let mut map = BTreeMap::new();
        while !pairs.bytes.is_empty() {
            map.insert(pairs.string()?, pairs.string()?);
        }
        Ok(map)
    }

    fn rest(&mut self) -> &'a [u8] {
        std::mem::take(&mut self.bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file of one chunk made by the `mcap` writer, as the Host makes them.
    fn written(messages: usize) -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .create(&mut out)
            .unwrap();
        let schema = writer.add_schema("s", "jsonschema", b"{}").unwrap();
        let channel = writer
            .add_channel(schema, "/t", "json", &BTreeMap::new())
            .unwrap();
        for i in 0..messages {
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: i as u32,
                log_time: i as u64,
                publish_time: i as u64,
            };
            writer
                .write_to_known_channel(&header, format!("{{\"i\":{i}}}").as_bytes())
                .unwrap();
        }
        writer.finish().unwrap();
        drop(writer);
        out.into_inner()
    }

    fn messages(file: &[u8]) -> Result<usize, Damage> {
        let mut count = 0;
        for record in records(&file[8..], 8) {
            if let Record::Chunk(content) = record? {
                for inner in records(&content, 0) {
                    count += usize::from(matches!(inner?, Record::Message { .. }));
                }
            }
        }
        Ok(count)
    }

    #[test]
    fn what_the_mcap_writer_writes_reads_back() {
        assert_eq!(messages(&written(50)), Ok(50));
    }

    #[test]
    fn a_chunk_declaring_more_than_it_may_is_refused_before_any_allocation() {
        let mut file = written(3);
        // The first chunk's uncompressed size: after the header record
        // (opcode, length, body) and the chunk's opcode, length and times.
        let header_len = u64::from_le_bytes(file[9..17].try_into().unwrap()) as usize;
        let chunk = 8 + 9 + header_len;
        assert_eq!(file[chunk], op::CHUNK);
        let size = chunk + 9 + 16;
        file[size..size + 8].copy_from_slice(&(4u64 << 60).to_le_bytes());
        assert!(matches!(messages(&file), Err(Damage::ChunkTooLarge { .. })));
    }

    #[test]
    fn a_bomb_stops_at_the_declared_size() {
        let zeros = vec![0u8; 64 << 20];
        let bomb = zstd::bulk::compress(&zeros, 19).unwrap();
        let mut body = Vec::new();
        body.extend(0u64.to_le_bytes());
        body.extend(0u64.to_le_bytes());
        // Declared within the ratio; the content is 64 MiB.
        body.extend((bomb.len() as u64 * 10).to_le_bytes());
        body.extend(0u32.to_le_bytes());
        body.extend(4u32.to_le_bytes());
        body.extend(b"zstd");
        body.extend((bomb.len() as u64).to_le_bytes());
        body.extend(&bomb);
        let mut file = vec![op::CHUNK];
        file.extend((body.len() as u64).to_le_bytes());
        file.extend(body);
        let read: Vec<_> = records(&file, 0).collect();
        assert!(
            matches!(read[..], [Err(Damage::Decompress { .. })]),
            "{read:?}"
        );
    }

    #[test]
    fn a_damaged_chunk_loses_only_its_own_messages() {
        let mut out = std::io::Cursor::new(Vec::new());
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(256))
            .create(&mut out)
            .unwrap();
        let channel = writer
            .add_channel(0, "/t", "json", &BTreeMap::new())
            .unwrap();
        for i in 0..100u32 {
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: i,
                log_time: u64::from(i),
                publish_time: u64::from(i),
            };
            writer
                .write_to_known_channel(&header, format!("{{\"i\":{i}}}").as_bytes())
                .unwrap();
        }
        writer.finish().unwrap();
        drop(writer);
        let mut file = out.into_inner();
        let chunks = records(&file[8..], 8)
            .filter(|r| matches!(r, Ok(Record::Chunk(_))))
            .count();
        assert!(chunks > 3, "{chunks} chunks");
        // The last byte of the second chunk's compressed data, flipped.
        let mut at = 8;
        let mut ends = Vec::new();
        while at + 9 <= file.len() {
            let length = u64::from_le_bytes(file[at + 1..at + 9].try_into().unwrap()) as usize;
            if file[at] == op::CHUNK {
                ends.push(at + 9 + length - 1);
            }
            at += 9 + length;
        }
        file[ends[1]] ^= 0xff;
        let read: Vec<_> = records(&file[8..], 8).collect();
        let damaged = read.iter().filter(|r| r.is_err()).count();
        let whole = read
            .iter()
            .filter(|r| matches!(r, Ok(Record::Chunk(_))))
            .count();
        assert_eq!((damaged, whole), (1, chunks - 1));
        assert!(matches!(read.last(), Some(Ok(Record::Footer))));
    }
}
