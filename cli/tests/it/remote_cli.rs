//! Logs read by URL, end to end: from an S3 endpoint on localhost (moto's server, started by
//! each test; see `common::servers`) and from an HTTP server answering range requests, each
//! compared with the same file read from disk, and the errors of a missing object, a missing
//! bucket and missing credentials.

use crate::common::servers::{Moto, RangeServer};
use crate::common::*;
use json::read_json;
use std::io::Write;
use std::path::Path;
use std::process::{Command, Output};

/// Environment variables for a run.
type Env = Vec<(&'static str, String)>;

/// Runs `calib` with `args` in an environment whose AWS settings are exactly `env`.
fn calib_env(args: &[&str], env: &[(&'static str, String)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_calib"));
    command.args(args);
    for (key, _) in std::env::vars() {
        if key.starts_with("AWS_") {
            command.env_remove(key);
        }
    }
    for (key, value) in env {
        command.env(key, value);
    }
    command.output().expect("cannot start calib")
}

/// The note `URL: fetched N of its M bytes in K request(s)` on standard error: (N, M, K).
#[track_caller]
fn fetched(stderr: &str, url: &str) -> (u64, u64, u64) {
    let line = stderr
        .lines()
        .find(|l| l.contains(&format!("{url}: fetched ")))
        .unwrap_or_else(|| panic!("no note of the bytes fetched from {url}:\n{stderr}"));
    let numbers: Vec<u64> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|w| w.parse().ok())
        .collect();
    let n = numbers.len();
    (numbers[n - 3], numbers[n - 2], numbers[n - 1])
}

/// An MCAP file of `frames` camera frames (`sensor_msgs/msg/Image`, 200 kB each, incompressible
/// bytes) in chunks of their own, then every message of quick.mcap (JointState): the camera
/// takes most of the file, and calib needs none of it.
fn with_camera(path: &Path, frames: usize) {
    let quick = std::fs::read(testdata("examples/quick.mcap")).unwrap();
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let options = mcap::WriteOptions::new().chunk_size(Some(256 * 1024));
    let mut writer = options.create(file).unwrap();
    let image = writer
        .add_schema("sensor_msgs/msg/Image", "ros2msg", b"uint8[] data")
        .unwrap();
    let camera = writer
        .add_channel(image, "/camera/image", "cdr", &Default::default())
        .unwrap();
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    for k in 0..frames {
        let frame: Vec<u8> = (0..200_000)
            .map(|_| {
                // xorshift64: bytes zstd cannot shrink.
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        let header = mcap::records::MessageHeader {
            channel_id: camera,
            sequence: k as u32,
            log_time: 1_000_000_000 + k as u64,
            publish_time: 1_000_000_000 + k as u64,
        };
        writer.write_to_known_channel(&header, &frame).unwrap();
    }
    // Flush the camera's chunk, so that the joint states start a chunk of their own.
    writer.flush().unwrap();
    // Copied by hand (`Writer::write` of another file's messages after a flush trips an
    // assertion of the mcap crate): quick.mcap has one JointState channel.
    let mut joints = None;
    for message in mcap::MessageStream::new(&quick).unwrap() {
        let message = message.unwrap();
        let channel = *joints.get_or_insert_with(|| {
            let schema = message.channel.schema.as_ref().unwrap();
            let id = writer
                .add_schema(&schema.name, &schema.encoding, &schema.data)
                .unwrap();
            writer
                .add_channel(
                    id,
                    &message.channel.topic,
                    &message.channel.message_encoding,
                    &message.channel.metadata,
                )
                .unwrap()
        });
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: message.sequence,
            log_time: message.log_time,
            publish_time: message.publish_time,
        };
        writer
            .write_to_known_channel(&header, &message.data)
            .unwrap();
    }
    writer.finish().unwrap();
}

/// Runs `calib csrr` on `local` and on `url` (with `env`) into folders of `dir`; asserts both
/// succeed with the same tables and the URL as the report's input; the standard error of the
/// remote run.
#[track_caller]
fn csrr_both(dir: &Path, local: &Path, url: &str, env: &[(&'static str, String)]) -> String {
    let here = dir.join("here");
    let there = dir.join("there");
    let _ = std::fs::remove_dir_all(&here);
    let _ = std::fs::remove_dir_all(&there);
    expect_exit(&calib_env(&["csrr", s(local), "-o", s(&here)], env), 0);
    let err = expect_exit(&calib_env(&["csrr", url, "-o", s(&there)], env), 0);
    for table in ["a.csv", "b.csv"] {
        let (want, got) = (here.join(table), there.join(table));
        assert!(
            std::fs::read(&want).unwrap() == std::fs::read(&got).unwrap(),
            "{url}: {table} differs from the local file's"
        );
    }
    let report = read_json(&there.join("report.json"));
    assert_eq!(report["inputs"][0], url, "{report}");
    err
}

fn len(path: &Path) -> u64 {
    std::fs::metadata(path).unwrap().len()
}

#[test]
fn s3_logs_calibrate_as_their_local_files_do_reading_only_what_they_need() {
    let Some(moto) = Moto::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    let env = moto.env();
    moto.bucket("fleet");
    let mcap = testdata("examples/quick.mcap");
    let csv = simulate_quick(dir.path(), "run.csv", &[]);
    let camera = dir.path().join("camera.mcap");
    with_camera(&camera, 20);
    for (key, file) in [
        ("r1/run.mcap", &mcap),
        ("r2/run.mcap", &mcap),
        ("r1/run.csv", &csv),
        ("r1/camera.mcap", &camera),
    ] {
        moto.put("fleet", key, &std::fs::read(file).unwrap());
    }
    // MCAP and CSV: the same maps, to the last digit.
    for (file, url) in [
        (&mcap, "s3://fleet/r1/run.mcap"),
        (&csv, "s3://fleet/r1/run.csv"),
    ] {
        let err = csrr_both(dir.path(), file, url, &env);
        let (bytes, of, requests) = fetched(&err, url);
        assert_eq!(of, len(file), "{url}");
        // The whole file at most, and the 128 bytes that told its format.
        assert!(bytes <= of + 128 && requests >= 1, "{url}: {bytes} bytes");
    }
    // An MCAP file that is mostly camera frames: only the joint states' chunks are fetched
    // (with the footer, the summary and the 128 bytes of its head).
    let url = "s3://fleet/r1/camera.mcap";
    let err = csrr_both(dir.path(), &camera, url, &env);
    let (bytes, of, requests) = fetched(&err, url);
    let quick = len(&mcap);
    assert!(of > 4_000_000, "{of}");
    assert!(
        bytes < quick + 64 * 1024,
        "{url}: {bytes} bytes in {requests} requests of {of}; quick.mcap is {quick}"
    );
    // Several logs in one call: a folder each, as local logs get.
    let out = dir.path().join("fleet");
    let o = calib_env(
        &[
            "csrr",
            "s3://fleet/r1/run.mcap",
            "s3://fleet/r2/run.mcap",
            "-o",
            s(&out),
        ],
        &env,
    );
    expect_exit(&o, 0);
    let a = std::fs::read(out.join("run/a.csv")).unwrap();
    assert_eq!(a, std::fs::read(out.join("run-2/a.csv")).unwrap());
    assert_eq!(a, std::fs::read(dir.path().join("here/a.csv")).unwrap());
}

#[test]
fn s3_bags_are_copied_within_a_limit_and_inspect_reads_urls() {
    let Some(moto) = Moto::start() else { return };
    let env = moto.env();
    moto.bucket("bags");
    let bag = testdata("rosbag/small_bag/small_bag_0.db3");
    moto.put(
        "bags",
        "day1/small_bag_0.db3",
        &std::fs::read(&bag).unwrap(),
    );
    let url = "s3://bags/day1/small_bag_0.db3";
    let local = calib_env(&["inspect", s(&bag), "--json"], &env);
    let remote = calib_env(&["inspect", url, "--json"], &env);
    expect_exit(&local, 0);
    let err = expect_exit(&remote, 0);
    let (local, remote): (serde_json::Value, serde_json::Value) = (
        serde_json::from_slice(&local.stdout).unwrap(),
        serde_json::from_slice(&remote.stdout).unwrap(),
    );
    assert_eq!(remote["log"], url);
    assert_eq!(local["topics"], remote["topics"]);
    assert_eq!(local["channels"], remote["channels"]);
    let notes = format!("{remote}{err}");
    assert!(notes.contains("temporary local copy"), "{notes}");
    // Above the limit: refused, naming the URL, its size and the option.
    let o = calib_env(&["inspect", url, "--max-copy", "0.01"], &env);
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &[url, "57344 bytes", "--max-copy"]);
}

#[test]
fn http_logs_are_read_by_range_and_every_byte_is_counted() {
    let dir = tempfile::tempdir().unwrap();
    let camera = dir.path().join("camera.mcap");
    with_camera(&camera, 20);
    let server = RangeServer::start(dir.path().to_path_buf());
    let url = server.url("camera.mcap");
    let work = tempfile::tempdir().unwrap();
    let before = server.sent();
    let err = csrr_both(work.path(), &camera, &url, &[]);
    let (bytes, of, _) = fetched(&err, &url);
    assert_eq!(of, len(&camera));
    // The server's count of the bytes it sent is calib's.
    assert_eq!(server.sent() - before, bytes);
    assert!(
        bytes < len(&testdata("examples/quick.mcap")) + 64 * 1024,
        "{bytes}"
    );
    // A missing file: exit 1, naming the URL.
    let missing = server.url("missing.mcap");
    let o = calib_env(&["csrr", &missing, "-o", s(&work.path().join("x"))], &[]);
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &[&missing, "404"]);
    assert!(!work.path().join("x").exists());
}

/// A static server that ignores byte ranges (Python's `http.server`, as many are) made calib say
/// "`URL`: `URL`: cannot read it: Operation not supported: Range request not supported …", the
/// URL twice and nothing to do. Now: exit 1, the URL once, what the server lacks and to download
/// the file.
#[test]
fn an_http_server_without_ranges_is_told_to_download_the_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        testdata("examples/quick.mcap"),
        dir.path().join("quick.mcap"),
    )
    .unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut server = Command::new("python3")
        .args([
            "-m",
            "http.server",
            &port.to_string(),
            "--bind",
            "127.0.0.1",
        ])
        .current_dir(dir.path())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("python3 -m http.server");
    let url = format!("http://127.0.0.1:{port}/quick.mcap");
    // Up to 10 s for the server to listen.
    for _ in 0..100 {
        if std::net::TcpStream::connect(("127.0.0.1", port)).is_ok() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let o = calib_env(&["inspect", &url], &[]);
    let _ = server.kill();
    let _ = server.wait();
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &["does not answer byte-range requests", "curl -O"]);
    assert_eq!(err.matches(&url).count(), 1, "{err}");
}

#[test]
fn a_missing_object_bucket_or_credentials_is_exit_1_naming_the_url() {
    let Some(moto) = Moto::start() else { return };
    let env = moto.env();
    moto.bucket("fleet");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let cases: [(&str, Env, &[&str]); 3] = [
        (
            "s3://fleet/missing.mcap",
            env.clone(),
            &["no object", "404"],
        ),
        (
            "s3://no-such-bucket/run.mcap",
            env.clone(),
            &["no object", "404"],
        ),
        (
            "s3://fleet/run.mcap",
            env.iter()
                .filter(|(k, _)| !k.contains("KEY"))
                .cloned()
                .collect(),
            &["credentials", "AWS_ACCESS_KEY_ID"],
        ),
    ];
    for (url, env, says) in cases {
        let o = calib_env(&["csrr", url, "-o", s(&out)], &env);
        let err = expect_exit(&o, 1);
        assert_mentions(&err, &[url]);
        assert_mentions(&err, says);
        assert!(!out.exists(), "{url}: outputs were written");
    }
}

/// A local file is never taken for a URL, nor a URL for a relative path: `s3:/x` (one slash)
/// is a path, and a URL is refused by `calib apply`, which rewrites local logs only.
#[test]
fn urls_and_paths_are_told_apart() {
    let dir = tempfile::tempdir().unwrap();
    let o = calib(&["inspect", "s3:/fleet/run.mcap"]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["s3:/fleet/run.mcap", "no such file"]);
    let table = dir.path().join("a.csv");
    let mut f = std::fs::File::create(&table).unwrap();
    writeln!(
        f,
        "angle_deg,error_arcsec,correction_arcsec\n0,0,0\n180,0,0"
    )
    .unwrap();
    let o = calib(&[
        "apply",
        s(&table),
        "s3://fleet/run.mcap",
        "-o",
        s(&dir.path().join("c.mcap")),
    ]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["s3://fleet/run.mcap", "download it first"]);
}
