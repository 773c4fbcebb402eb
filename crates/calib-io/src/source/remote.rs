//! Objects in S3, Google Cloud Storage, Azure Blob Storage or behind an HTTP server, read by
//! byte range through the `object_store` crate (Apache Arrow's, which the clouds' Rust users
//! share) on a small current-thread tokio runtime of the source's own: the library stays
//! synchronous, and each read blocks until its range has arrived.
//!
//! # Credentials and options
//! Each store's builder starts from the environment as the cloud's own tools read it
//! (`from_env`: `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_SESSION_TOKEN`,
//! `AWS_REGION`, `AWS_ENDPOINT_URL`, `AWS_ALLOW_HTTP`, …; `GOOGLE_SERVICE_ACCOUNT`,
//! `GOOGLE_APPLICATION_CREDENTIALS`; `AZURE_STORAGE_ACCOUNT_NAME`, `AZURE_STORAGE_ACCOUNT_KEY`,
//! …), then takes the caller's options (the same keys in lower case, e.g. `aws_endpoint`);
//! an unknown key is an error, not ignored. An `http(s)://` URL that is not a cloud's is read from
//! the server as it is, with the client options (`allow_http`, `timeout`, …).
//!
//! # Requests
//! A chunk's read ([`ByteSource::read_exact_at`]) is one request for its range and, where the
//! reader said which ranges follow ([`ByteSource::plan`]), for those that lie within
//! [`GAP`] of it, up to [`SPAN`] bytes in all: object stores charge per request, in latency
//! and in money, far more than per byte (a local S3 server, moto, copies the whole object for
//! every range it serves). The requests are made one at a time, so that the worker wanting
//! the next chunk finds it among the kept ranges. A
//! reader going front to back ([`ByteSource::read_at`]: the footer, the summary, a CSV's
//! buffer) fetches [`BLOCK`] bytes from its offset, so that reading a file front to back costs
//! one request per block, not per buffer. The last [`BLOCKS`] ranges fetched are kept: a read
//! within one costs no request (the chunks the first pass over an MCAP file read to learn its
//! topics are read again at once). Failed requests are retried ([`retry`]).

use std::io;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::Bytes;
use object_store::aws::AmazonS3Builder;
use object_store::azure::MicrosoftAzureBuilder;
use object_store::gcp::GoogleCloudStorageBuilder;
use object_store::http::HttpBuilder;
use object_store::path::Path as ObjectPath;
use object_store::{ClientOptions, ObjectStore, ObjectStoreExt, ObjectStoreScheme, RetryConfig};
use url::Url;

use super::{ByteSource, Counter, Fetched, StorageOptions};
use crate::Error;

/// What a front-to-back read fetches from its offset, kept for the reads that follow.
pub const BLOCK: usize = 1 << 20;

/// Ranges kept for the reads that follow: the head, footer and summary blocks, and the spans
/// the first pass over an MCAP file fetched, for the second to find (at most 48 MiB).
pub const BLOCKS: usize = 6;

/// The largest request for several planned ranges.
pub const SPAN: u64 = 8 << 20;

/// The largest gap between two planned ranges fetched in one request (an MCAP file's message
/// indexes between two chunks; a chunk calib does not need is usually larger).
pub const GAP: u64 = 512 << 10;

/// An object read by byte range (see the [module docs](self)).
pub(super) struct ObjectSource {
    url: String,
    store: Arc<dyn ObjectStore>,
    location: ObjectPath,
    len: u64,
    runtime: tokio::runtime::Runtime,
    counter: Counter,
    /// The last ranges fetched, each with its offset, the latest last.
    blocks: Mutex<Vec<(u64, Bytes)>>,
    /// The ranges a reader said it will read ([`ByteSource::plan`]), in file order.
    planned: Mutex<Vec<(u64, u64)>>,
    /// Held while a planned read fetches, so that one request serves the reads it covers; the
    /// end of the last planned range fetched.
    fetching: Mutex<u64>,
}

impl std::fmt::Debug for ObjectSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectSource")
            .field("url", &self.url)
            .field("len", &self.len)
            .finish()
    }
}

/// How failed requests are retried: a few times within 30 s (`object_store`'s default waits up
/// to 3 minutes, too long to learn that a host cannot be reached).
fn retry() -> RetryConfig {
    RetryConfig {
        max_retries: 3,
        retry_timeout: Duration::from_secs(30),
        ..RetryConfig::default()
    }
}

/// `key` is not an option of this store: an error naming it.
fn unknown_key(url: &str, key: &str, store: &str) -> Error {
    remote_error(
        url,
        format!(
            "`{key}` is not an option of {store}; name its options as `object_store` does \
             (e.g. aws_endpoint, aws_access_key_id, aws_region, aws_allow_http for S3)"
        ),
    )
}

fn remote_error(url: &str, message: String) -> Error {
    Error::Data {
        path: PathBuf::from(url),
        message,
    }
}

/// Builds `$builder` from the environment, the URL and the options.
macro_rules! configured {
    ($builder:expr, $url:expr, $options:expr, $store:expr) => {{
        let mut builder = $builder.with_url($url);
        for (key, value) in $options {
            let parsed = key
                .to_ascii_lowercase()
                .parse()
                .map_err(|_| unknown_key($url, key, $store))?;
            builder = builder.with_config(parsed, value.clone());
        }
        builder.with_retry(retry())
    }};
}

/// Where credentials are looked for, as a user is told when none are found or they are refused.
const CREDENTIALS: &str = "set them in the environment as the cloud's own tools take them — \
     AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (S3), GOOGLE_APPLICATION_CREDENTIALS (GCS), \
     AZURE_STORAGE_ACCOUNT_NAME and AZURE_STORAGE_ACCOUNT_KEY (Azure) — or, from Python, in \
     `storage_options`";

/// What a failed request means for the user, and what to do.
fn explain(url: &str, e: &object_store::Error) -> Error {
    remote_error(url, what_failed(e))
}

/// [`explain`]'s message, without the URL (for an I/O error the reader names the URL with).
fn what_failed(e: &object_store::Error) -> String {
    use object_store::Error as E;
    match e {
        E::NotFound { .. } => "there is no object at this URL (404); check the bucket and the \
                               key (or the address) — a log's name is case-sensitive"
            .to_string(),
        E::PermissionDenied { .. } => format!(
            "access is refused (403): the credentials given may not read this object; check \
             them and the bucket's policy ({e})"
        ),
        E::Unauthenticated { .. } => {
            format!("the request was not authenticated (401): {CREDENTIALS} ({e})")
        }
        E::NotSupported { .. } => format!(
            "the server does not answer byte-range requests (HTTP `Range`), by which calib reads \
             a log where it is; download the file (e.g. `curl -O URL`) and give calib the copy \
             ({e})"
        ),
        _ => {
            let text = e.to_string();
            let lower = text.to_ascii_lowercase();
            if lower.contains("credential") || lower.contains("token") {
                format!("no credentials were found: {CREDENTIALS} ({text})")
            } else if lower.contains("bucket") && lower.contains("not") {
                format!("the bucket does not exist or cannot be reached: check its name ({text})")
            } else if lower.contains("connect")
                || lower.contains("dns")
                || lower.contains("timed out")
                || lower.contains("error sending request")
            {
                format!(
                    "the storage cannot be reached: check the network, and the endpoint \
                     (AWS_ENDPOINT_URL, or `aws_endpoint` in `storage_options`) ({text})"
                )
            } else {
                format!("cannot read it: {text}")
            }
        }
    }
}

impl ObjectSource {
    /// Opens the object at `url` and learns its length (see the [module docs](self)).
    pub(super) fn open(url: &str, options: &StorageOptions) -> Result<Self, Error> {
        let parsed = Url::parse(url).map_err(|e| {
            remote_error(url, format!("this is not a valid URL ({e}); write it as s3://BUCKET/KEY, gs://BUCKET/KEY, az://CONTAINER/KEY or https://HOST/PATH"))
        })?;
        let (scheme, location) = ObjectStoreScheme::parse(&parsed).map_err(|e| {
            remote_error(url, format!("calib cannot read this URL ({e}); write it as s3://BUCKET/KEY, gs://BUCKET/KEY, az://CONTAINER/KEY or https://HOST/PATH"))
        })?;
        let built = match scheme {
            ObjectStoreScheme::AmazonS3 => {
                configured!(AmazonS3Builder::from_env(), url, options, "Amazon S3")
                    .build()
                    .map(|s| Arc::new(s) as Arc<dyn ObjectStore>)
            }
            ObjectStoreScheme::GoogleCloudStorage => configured!(
                GoogleCloudStorageBuilder::from_env(),
                url,
                options,
                "Google Cloud Storage"
            )
            .build()
            .map(|s| Arc::new(s) as Arc<dyn ObjectStore>),
            ObjectStoreScheme::MicrosoftAzure => configured!(
                MicrosoftAzureBuilder::from_env(),
                url,
                options,
                "Azure Blob Storage"
            )
            .build()
            .map(|s| Arc::new(s) as Arc<dyn ObjectStore>),
            ObjectStoreScheme::Http => {
                let base = &parsed[..url::Position::BeforePath];
                // A plain `http://` URL was written on purpose: no need to allow it twice.
                let mut client = ClientOptions::new().with_allow_http(parsed.scheme() == "http");
                for (key, value) in options {
                    let parsed = key
                        .to_ascii_lowercase()
                        .parse()
                        .map_err(|_| unknown_key(url, key, "an HTTP server"))?;
                    client = client.with_config(parsed, value.clone());
                }
                HttpBuilder::new()
                    .with_url(base)
                    .with_client_options(client)
                    .with_retry(retry())
                    .build()
                    .map(|s| Arc::new(s) as Arc<dyn ObjectStore>)
            }
            _ => {
                return Err(remote_error(
                    url,
                    "calib reads s3://, gs://, az:// and http(s):// URLs; name a local file by \
                     its path"
                        .into(),
                ));
            }
        };
        let store = built.map_err(|e| {
            remote_error(
                url,
                format!(
                    "the storage cannot be set up ({e}); check the URL and the options \
                     (AWS_REGION, AWS_ENDPOINT_URL, …, or `storage_options`)"
                ),
            )
        })?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| remote_error(url, format!("cannot start the network runtime: {e}")))?;
        let meta = runtime
            .block_on(store.head(&location))
            .map_err(|e| explain(url, &e))?;
        Ok(ObjectSource {
            url: url.to_string(),
            store,
            location,
            len: meta.size,
            runtime,
            counter: Counter::default(),
            blocks: Mutex::new(Vec::new()),
            planned: Mutex::new(Vec::new()),
            fetching: Mutex::new(0),
        })
    }

    /// Copies what a kept block holds from `offset` into `buf` (all of `buf` or nothing if
    /// `whole`): the bytes copied.
    fn kept(&self, offset: u64, buf: &mut [u8], whole: bool) -> usize {
        let blocks = self.blocks.lock().unwrap_or_else(|e| e.into_inner());
        for (at, bytes) in blocks.iter().rev() {
            let Some(from) = offset
                .checked_sub(*at)
                .and_then(|d| usize::try_from(d).ok())
                .filter(|&d| d < bytes.len())
            else {
                continue;
            };
            let n = buf.len().min(bytes.len() - from);
            if whole && n < buf.len() {
                continue;
            }
            buf[..n].copy_from_slice(&bytes[from..from + n]);
            return n;
        }
        0
    }

    /// The request for the read `offset..end`: itself or, if it is a planned range, from the
    /// first planned range before it not fetched yet (at or after `fetched_until`: another
    /// worker, a chunk behind, will want it) to the last after it, each within [`GAP`] of the
    /// one before, [`SPAN`] bytes in all.
    fn span(&self, offset: u64, end: u64, fetched_until: u64) -> (u64, u64) {
        let planned = self.planned.lock().unwrap_or_else(|e| e.into_inner());
        let Ok(first) = planned.binary_search_by_key(&offset, |&(at, _)| at) else {
            return (offset, end);
        };
        let mut start = offset;
        for &(at, n) in planned[..first].iter().rev() {
            let prev_end = at.saturating_add(n);
            if at < fetched_until || prev_end > start || start - prev_end > GAP || end - at > SPAN {
                break;
            }
            start = at;
        }
        let mut span_end = end;
        for &(at, n) in &planned[first + 1..] {
            let next_end = at.saturating_add(n);
            if at < span_end || at - span_end > GAP || next_end - start > SPAN {
                break;
            }
            span_end = next_end;
        }
        (start, span_end.min(self.len))
    }

    /// Keeps `bytes`, fetched from `offset`, in place of the oldest block kept.
    fn keep(&self, offset: u64, bytes: Bytes) {
        let mut blocks = self.blocks.lock().unwrap_or_else(|e| e.into_inner());
        if blocks.len() >= BLOCKS {
            blocks.remove(0);
        }
        blocks.push((offset, bytes));
    }

    /// Fetches `range` (one request).
    fn fetch(&self, range: Range<u64>) -> io::Result<Bytes> {
        let bytes = self
            .runtime
            .block_on(self.store.get_range(&self.location, range.clone()))
            .map_err(|e| io::Error::other(what_failed(&e)))?;
        self.counter.add(bytes.len());
        if bytes.len() as u64 != range.end - range.start {
            return Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                format!(
                    "the server sent {} bytes for a range of {}; the object changed while it \
                     was read?",
                    bytes.len(),
                    range.end - range.start
                ),
            ));
        }
        Ok(bytes)
    }
}

impl ByteSource for ObjectSource {
    fn len(&self) -> u64 {
        self.len
    }

    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let end = offset
            .checked_add(buf.len() as u64)
            .filter(|&end| end <= self.len)
            .ok_or(io::ErrorKind::UnexpectedEof)?;
        if buf.is_empty() || self.kept(offset, buf, true) > 0 {
            return Ok(());
        }
        let mut fetched_until = self.fetching.lock().unwrap_or_else(|e| e.into_inner());
        // Another read may have fetched it meanwhile.
        if self.kept(offset, buf, true) > 0 {
            return Ok(());
        }
        let (start, span_end) = self.span(offset, end, *fetched_until);
        let bytes = self.fetch(start..span_end)?;
        let from = (offset - start) as usize;
        buf.copy_from_slice(&bytes[from..from + buf.len()]);
        self.keep(start, bytes);
        *fetched_until = (*fetched_until).max(span_end);
        Ok(())
    }

    fn plan(&self, ranges: &[(u64, u64)]) {
        *self.planned.lock().unwrap_or_else(|e| e.into_inner()) = ranges.to_vec();
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() || offset >= self.len {
            return Ok(0);
        }
        let n = self.kept(offset, buf, false);
        if n > 0 {
            return Ok(n);
        }
        let end = offset
            .saturating_add(BLOCK.max(buf.len()) as u64)
            .min(self.len);
        let bytes = self.fetch(offset..end)?;
        let n = buf.len().min(bytes.len());
        buf[..n].copy_from_slice(&bytes[..n]);
        self.keep(offset, bytes);
        Ok(n)
    }

    fn is_remote(&self) -> bool {
        true
    }

    fn fetched(&self) -> Fetched {
        self.counter.get()
    }
}
