//! Errors of reading logs and tables and of writing outputs.

use std::path::PathBuf;

/// An error that names the file and, where it applies, the line, message and channel.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file could not be opened or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The file's extension names no format calib reads.
    #[error("{}: unknown log format; calib reads {}", path.display(), crate::log::formats_read())]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// A CSV file (log, table, readings) has bad content at a line.
    #[error("{}: line {line}{}: {message}", path.display(), channel.as_ref().map(|c| format!(", column `{c}`")).unwrap_or_default())]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number (the header is line 1).
        line: u64,
        /// The column concerned, where one is.
        channel: Option<String>,
        /// What is wrong and what to do.
        message: String,
    },
    /// An MCAP file has bad content.
    #[error("{}: {}{}{message}", path.display(), message_index.map(|i| format!("message {i}: ")).unwrap_or_default(), channel.as_ref().map(|c| format!("channel `{c}`: ")).unwrap_or_default())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// 0-based index of the message in file order, where one is concerned.
        message_index: Option<u64>,
        /// The channel (joint name, JSON field or topic) concerned, where one is.
        channel: Option<String>,
        /// What is wrong and what to do.
        message: String,
    },
    /// A rosbag2 bag (its `metadata.yaml` or a `.db3` file) has bad content.
    #[error("{}: {}{}{}{message}", path.display(), table.as_ref().map(|t| format!("table `{t}`: ")).unwrap_or_default(), message_id.map(|i| format!("message id {i}: ")).unwrap_or_default(), topic.as_ref().map(|t| format!("topic `{t}`: ")).unwrap_or_default())]
    Bag {
        /// The file (or bag directory).
        path: PathBuf,
        /// The SQLite table concerned, where one is.
        table: Option<String>,
        /// The `id` of the row of `messages` concerned, where one is.
        message_id: Option<i64>,
        /// The topic concerned, where one is.
        topic: Option<String>,
        /// What is wrong and what to do.
        message: String,
    },
    /// A ROS 1 bag has bad content.
    #[error("{}: {}{}{}{message}", path.display(), byte_offset.map(|b| format!("byte {b}: ")).unwrap_or_default(), message_index.map(|i| format!("message {i}: ")).unwrap_or_default(), topic.as_ref().map(|t| format!("topic `{t}`: ")).unwrap_or_default())]
    Ros1Bag {
        /// The bag file.
        path: PathBuf,
        /// Where the record concerned starts in the file (for a message, its chunk's record).
        byte_offset: Option<u64>,
        /// 0-based index of the message in the order read (time order), where one is concerned.
        message_index: Option<u64>,
        /// The topic (or joint) concerned, where one is.
        topic: Option<String>,
        /// What is wrong and what to do.
        message: String,
    },
    /// What a writer was given cannot be written as a valid file; nothing was written.
    #[error("{}: cannot write: {message}", path.display())]
    Write {
        /// The file that was to be written.
        path: PathBuf,
        /// What is wrong and what to do.
        message: String,
    },
    /// A file holds no samples.
    #[error("{}: the log holds no samples", path.display())]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// A file's content is inconsistent as a whole (e.g. readings missing from a set).
    #[error("{}: {message}", path.display())]
    Data {
        /// The file.
        path: PathBuf,
        /// What is wrong and what to do.
        message: String,
    },
    /// An uncertainty budget (TOML) is malformed or inconsistent.
    #[error("{}: {}{}{message}", path.display(), line.map(|l| format!("line {l}: ")).unwrap_or_default(), component.as_ref().map(|c| format!("component `{c}`: ")).unwrap_or_default())]
    Budget {
        /// The file.
        path: PathBuf,
        /// 1-based line, where the TOML parser names one.
        line: Option<u64>,
        /// The component concerned, by name (or `#N` before its name is known).
        component: Option<String>,
        /// What is wrong and what to write instead.
        message: String,
    },
}

impl Error {
    /// The error with its file renamed where `renames` lists it (`(from, to)`): a bag's
    /// temporary copies named as the splits they came from.
    pub(crate) fn renamed(mut self, renames: &[(PathBuf, PathBuf)]) -> Self {
        let path = match &mut self {
            Error::Io { path, .. }
            | Error::UnknownFormat { path }
            | Error::Csv { path, .. }
            | Error::Mcap { path, .. }
            | Error::Bag { path, .. }
            | Error::Ros1Bag { path, .. }
            | Error::Write { path, .. }
            | Error::Empty { path }
            | Error::Data { path, .. }
            | Error::Budget { path, .. } => path,
        };
        if let Some((_, to)) = renames.iter().find(|(from, _)| from == path) {
            *path = to.clone();
        }
        self
    }
}

/// Why a named pipe (or another stream: a terminal, `/dev/stdin`) cannot be read as a `what`
/// (`log`, `table`): calib reads its first lines to find its layout, then reads it again from
/// the start, and a stream gives its bytes only once.
pub(crate) fn read_twice(what: &str) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        format!(
            "this is a named pipe or another stream, which can be read only once, and calib \
             reads a {what} twice (its first lines to find its layout, then the whole); save it \
             to a file first (`cat PIPE > FILE`) and give that"
        ),
    )
}

/// An [`Error::Csv`] for `path` at a 1-based `line`, naming `column` where one is concerned.
pub(crate) fn csv_error(
    path: &std::path::Path,
    line: u64,
    column: Option<&str>,
    message: String,
) -> Error {
    Error::Csv {
        path: path.to_path_buf(),
        line,
        channel: column.map(str::to_string),
        message,
    }
}

/// A CSV reader over `input` that trims fields, and its header row (line 1).
pub(crate) fn csv_with_headers<R: std::io::Read>(
    input: R,
    path: &std::path::Path,
) -> Result<(csv::Reader<R>, csv::StringRecord), Error> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(input);
    let headers = reader
        .headers()
        .map_err(|e| csv_error(path, 1, None, e.to_string()))?
        .clone();
    Ok((reader, headers))
}
