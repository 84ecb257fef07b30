//! A network camera streaming MJPEG over HTTP, as IP cameras,
//! `mjpg-streamer` and `ustreamer` serve it: one `GET` answered by a
//! `multipart/x-mixed-replace` body, a JPEG per part. A thread reads the
//! stream as fast as it comes and keeps only the newest frame, so a Host
//! that looks less often than the camera sends never sees an old one; when
//! the stream breaks it connects again, backing off to a few seconds.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use tracing::debug;
use vl_core::CameraModel;

use super::pixels::{MAX_CAMERA_SIDE, declared_size};
use super::slot::FrameSlot;
use crate::drivers::{Camera, CameraError, Captured, believed};

/// No JPEG part is larger than this, nor a header line longer than
/// `MAX_LINE`, nor a part's headers more than `MAX_HEADERS`: a stream that
/// breaks these is no camera's.
const MAX_PART: usize = 16 << 20;
const MAX_LINE: usize = 8 << 10;
const MAX_HEADERS: usize = 64;
/// A camera that sends nothing for this long is gone.
const SILENT: Duration = Duration::from_secs(2);
/// Reconnecting backs off from the first to the second.
const RETRY: (Duration, Duration) = (Duration::from_millis(200), Duration::from_secs(3));
/// How long `open` waits for the first frame, which gives the image's size.
const FIRST_FRAME: Duration = Duration::from_secs(5);

/// Where the stream is: host, port and the request's path.
#[derive(Debug, Clone, PartialEq)]
struct Address {
    host: String,
    port: u16,
    path: String,
}

impl Address {
    fn parse(url: &str) -> Result<Address, CameraError> {
        let refused = |why: &str| CameraError::Address(format!("'{url}': {why}"));
        let parsed = url::Url::parse(url).map_err(|e| match e {
            url::ParseError::EmptyHost => refused("it names no host"),
            url::ParseError::InvalidPort => refused("its port is no port number"),
            e => refused(&e.to_string()),
        })?;
        if parsed.scheme() != "http" {
            return Err(CameraError::Address(format!(
                "'{url}' is no HTTP camera: it must start with http:// (https is not read)"
            )));
        }
        if !parsed.username().is_empty() || parsed.password().is_some() {
            return Err(refused(
                "a user and password in the address are not supported",
            ));
        }
        // An IPv6 address unbracketed, as a socket address takes it.
        let host = (parsed.host_str())
            .map(|h| h.trim_start_matches('[').trim_end_matches(']').to_owned())
            .ok_or_else(|| refused("it names no host"))?;
        Ok(Address {
            host,
            port: parsed.port_or_known_default().unwrap_or(80),
            path: parsed[url::Position::BeforePath..url::Position::AfterQuery].to_owned(),
        })
    }
}

/// A camera at an `http://` URL serving MJPEG.
pub struct HttpCamera {
    url: String,
    model: CameraModel,
    shared: Arc<FrameSlot>,
    seen: u64,
}

impl HttpCamera {
    /// Starts reading `url`; the camera is seen through `model`, or
    /// (without one) as a camera looking straight down on a `floor_mm`
    /// floor at `fps`, its size taken from its first frame.
    pub fn open(
        url: &str,
        model: Option<CameraModel>,
        floor_mm: (f64, f64),
        fps: f64,
    ) -> Result<HttpCamera, CameraError> {
        let address = Address::parse(url)?;
        let shared = Arc::new(FrameSlot::default());
        let reader = shared.clone();
        thread::Builder::new()
            .name("vl-http-camera".into())
            .spawn(move || read_forever(&address, &reader))
            .map_err(|e| CameraError::Setup(format!("cannot start reading {url}: {e}")))?;
        let model = match model {
            Some(model) => model,
            None => {
                let newest = shared.wait_for(FIRST_FRAME, |n| n.jpeg.is_some());
                let Some((jpeg, _)) = &newest.jpeg else {
                    let why = newest
                        .error
                        .clone()
                        .unwrap_or_else(|| "nothing came".into());
                    return Err(CameraError::Silent(format!(
                        "no frame from {url} within {} s ({why})",
                        FIRST_FRAME.as_secs()
                    )));
                };
                let first =
                    |e: String| CameraError::Frame(format!("the first frame from {url}: {e}"));
                match declared_size(jpeg) {
                    Some((w, h)) if w <= MAX_CAMERA_SIDE && h <= MAX_CAMERA_SIDE => {}
                    Some((w, h)) => {
                        return Err(first(format!(
                            "{w}×{h} px, over the {MAX_CAMERA_SIDE} px a camera may have"
                        )));
                    }
                    None => return Err(first("no JPEG frame header".into())),
                }
                let image = vl_core::decode_image(jpeg, Some(image::ImageFormat::Jpeg))
                    .map_err(|e| first(e.to_string()))?;
                believed(None, floor_mm, image.width(), fps)
            }
        };
        shared.lock().size = Some((model.width_px, model.height_px));
        Ok(HttpCamera {
            url: url.to_owned(),
            model,
            shared,
            seen: 0,
        })
    }
}

impl Camera for HttpCamera {
    fn model(&self) -> CameraModel {
        self.model
    }

    fn grab(&mut self) -> Result<Captured, CameraError> {
        self.shared.grab(&mut self.seen, &self.model, &self.url)
    }
}

/// Reads the stream, again and again, until the camera is dropped.
fn read_forever(address: &Address, shared: &Arc<FrameSlot>) {
    let mut wait = RETRY.0;
    // Ends when the camera (the other holder of `shared`) is gone.
    while Arc::strong_count(shared) > 1 {
        let error = match stream(address, shared) {
            Ok(()) => "the camera ended its stream".to_owned(),
            Err(e) => e,
        };
        debug!("{}:{}: {error}", address.host, address.port);
        let got_frames = {
            let mut newest = shared.lock();
            newest.error = Some(error);
            newest.jpeg.is_some()
        };
        shared.notify();
        thread::sleep(wait);
        wait = if got_frames {
            RETRY.0
        } else {
            (wait * 2).min(RETRY.1)
        };
        shared.lock().jpeg = None;
    }
}

/// One connection: the request, the answer's headers, then parts until
/// the stream breaks.
fn stream(address: &Address, shared: &Arc<FrameSlot>) -> Result<(), String> {
    let socket = (address.host.as_str(), address.port)
        .to_socket_addrs()
        .map_err(|e| format!("cannot find {}: {e}", address.host))?
        .next()
        .ok_or_else(|| format!("{} has no address", address.host))?;
    let mut tcp =
        TcpStream::connect_timeout(&socket, SILENT).map_err(|e| format!("cannot connect: {e}"))?;
    tcp.set_read_timeout(Some(SILENT))
        .map_err(|e| e.to_string())?;
    tcp.set_write_timeout(Some(SILENT))
        .map_err(|e| e.to_string())?;
    write!(
        tcp,
        "GET {} HTTP/1.1\r\nHost: {}\r\nUser-Agent: vl\r\nAccept: multipart/x-mixed-replace, image/jpeg\r\nConnection: close\r\n\r\n",
        address.path, address.host
    )
    .map_err(|e| format!("cannot ask for the stream: {e}"))?;
    let mut reader = BufReader::new(tcp);
    let answer = answer(&mut reader)?;
    let content_type = header(&answer, "content-type").unwrap_or_default();
    let boundary = content_type
        .split(';')
        .filter_map(|p| p.trim().strip_prefix("boundary="))
        .next()
        .map(|b| b.trim_matches('"').to_owned())
        .filter(|_| content_type.to_ascii_lowercase().starts_with("multipart/"))
        .ok_or_else(|| format!("the camera sends '{content_type}', not an MJPEG stream"))?;
    shared.lock().error = None;
    loop {
        // Up to the boundary line (some cameras put blank lines first, some
        // write the boundary with its dashes in the header too).
        let delimiter = boundary.trim_start_matches('-');
        let mut skipped = 0;
        loop {
            let text = line(&mut reader)?;
            let core = text.trim().trim_start_matches('-');
            if core == delimiter {
                break;
            }
            if core.strip_suffix("--") == Some(delimiter) {
                return Ok(());
            }
            skipped += 1;
            if skipped > MAX_HEADERS {
                return Err("no part boundary in the stream".into());
            }
        }
        let part = headers(&mut reader)?;
        let jpeg = match header(&part, "content-length") {
            Some(length) => {
                let length: usize = length
                    .trim()
                    .parse()
                    .map_err(|_| format!("a part of length '{length}'"))?;
                if length > MAX_PART {
                    return Err(format!("a {length}-byte part, over {MAX_PART}"));
                }
                let mut jpeg = vec![0; length];
                reader
                    .read_exact(&mut jpeg)
                    .map_err(|e| format!("the stream broke: {e}"))?;
                jpeg
            }
            None => until_jpeg_end(&mut reader)?,
        };
        // A camera that says when it took the frame (ustreamer's and
        // mjpg-streamer's X-Timestamp, Unix seconds) is believed.
        let taken = header(&part, "x-timestamp")
            .and_then(|t| t.trim().parse::<f64>().ok())
            .and_then(|t| {
                let now = SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .ok()?
                    .as_secs_f64();
                let age = now - t;
                (0.0..1.0)
                    .contains(&age)
                    .then(|| Instant::now() - Duration::from_secs_f64(age))
            })
            .unwrap_or_else(Instant::now);
        if !shared.keep(jpeg, taken) {
            debug!("a frame not of the camera's size dropped as it came");
            continue;
        }
        if Arc::strong_count(shared) == 1 {
            return Ok(());
        }
    }
}

/// A part with no length: its bytes up to JPEG's end marker.
fn until_jpeg_end(reader: &mut impl BufRead) -> Result<Vec<u8>, String> {
    let mut jpeg = Vec::new();
    loop {
        let mut byte = [0u8];
        reader
            .read_exact(&mut byte)
            .map_err(|e| format!("the stream broke: {e}"))?;
        jpeg.push(byte[0]);
        if jpeg.ends_with(&[0xFF, 0xD9]) {
            return Ok(jpeg);
        }
        if jpeg.len() > MAX_PART {
            return Err(format!("a part over {MAX_PART} bytes"));
        }
    }
}

/// One header line, without its CRLF.
fn line(reader: &mut impl BufRead) -> Result<String, String> {
    let mut bytes = Vec::new();
    let n = reader
        .take(MAX_LINE as u64)
        .read_until(b'\n', &mut bytes)
        .map_err(|e| format!("the stream broke: {e}"))?;
    if n == 0 {
        return Err("the camera closed the connection".into());
    }
    if !bytes.ends_with(b"\n") {
        return Err(format!("a header line over {MAX_LINE} bytes"));
    }
    Ok(String::from_utf8_lossy(&bytes).trim_end().to_owned())
}

/// A head's lines up to the blank one, each within `MAX_LINE`, at most
/// `MAX_HEADERS` of them (and a status line), as HTTP writes them.
fn head(reader: &mut impl BufRead) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    for _ in 0..MAX_HEADERS + 2 {
        let text = line(reader)?;
        bytes.extend_from_slice(text.as_bytes());
        bytes.extend_from_slice(b"\r\n");
        if text.is_empty() {
            return Ok(bytes);
        }
    }
    Err(format!("over {MAX_HEADERS} header lines"))
}

/// httparse's headers as (lower-case name, value).
fn owned(headers: &[httparse::Header<'_>]) -> Vec<(String, String)> {
    headers
        .iter()
        .map(|h| {
            let value = String::from_utf8_lossy(h.value).trim().to_owned();
            (h.name.to_ascii_lowercase(), value)
        })
        .collect()
}

/// The answer's status and headers, read by httparse: a 200, or why not.
fn answer(reader: &mut impl BufRead) -> Result<Vec<(String, String)>, String> {
    let bytes = head(reader)?;
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let mut response = httparse::Response::new(&mut headers);
    match response.parse(&bytes) {
        Ok(httparse::Status::Complete(_)) if response.code == Some(200) => {
            Ok(owned(response.headers))
        }
        Ok(httparse::Status::Complete(_)) => Err(format!(
            "the camera answered {} {}",
            response.code.unwrap_or_default(),
            response.reason.unwrap_or_default()
        )),
        Ok(httparse::Status::Partial) | Err(_) => {
            let first = String::from_utf8_lossy(&bytes);
            let first = first.lines().next().unwrap_or_default();
            Err(format!("the camera answered '{first}', which is no HTTP"))
        }
    }
}

/// A part's headers, read by httparse.
fn headers(reader: &mut impl BufRead) -> Result<Vec<(String, String)>, String> {
    let bytes = head(reader)?;
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    match httparse::parse_headers(&bytes, &mut headers) {
        Ok(httparse::Status::Complete((_, parsed))) => Ok(owned(parsed)),
        _ => Err("a part's headers are no HTTP headers".into()),
    }
}

fn header<'a>(headers: &'a [(String, String)], name: &str) -> Option<&'a str> {
    headers
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, v)| v.as_str())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_are_read_or_refused_with_a_reason() {
        let a = Address::parse("http://10.0.0.5:8080/?action=stream").unwrap();
        assert_eq!(
            (a.host.as_str(), a.port, a.path.as_str()),
            ("10.0.0.5", 8080, "/?action=stream")
        );
        let a = Address::parse("http://camera.lab").unwrap();
        assert_eq!(
            (a.host.as_str(), a.port, a.path.as_str()),
            ("camera.lab", 80, "/")
        );
        let a = Address::parse("http://[::1]:81/stream").unwrap();
        assert_eq!((a.host.as_str(), a.port), ("::1", 81));
        for (url, says) in [
            ("https://cam/", "must start with http://"),
            ("http://:80/", "names no host"),
            ("http://cam:http/", "no port number"),
            ("http://me:pw@cam/", "user and password"),
        ] {
            let e = Address::parse(url).unwrap_err().to_string();
            assert!(e.contains(says), "{url}: {e}");
        }
    }
}
