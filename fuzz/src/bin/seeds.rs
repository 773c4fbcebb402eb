//! Writes the committed seed corpora under `fuzz/corpus/<target>/` (run from `fuzz/`:
//! `cargo run --bin seeds`). Seeds are small well-formed inputs of every kind the readers accept,
//! so the fuzzer starts from deep inside each format.

use calib_fuzz::{Layout, wrap_messages};
use std::path::Path;

/// A JointState message in CDR, little- or big-endian.
fn joint_state(
    sec: i32,
    nanosec: u32,
    names: &[&str],
    position: &[f64],
    big_endian: bool,
) -> Vec<u8> {
    let mut out = vec![0, if big_endian { 0 } else { 1 }, 0, 0];
    let u32_at = |out: &mut Vec<u8>, v: u32| {
        while (out.len() - 4) % 4 != 0 {
            out.push(0);
        }
        out.extend(if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        });
    };
    let string = |out: &mut Vec<u8>, s: &str| {
        u32_at(out, s.len() as u32 + 1);
        out.extend(s.as_bytes());
        out.push(0);
    };
    let f64_seq = |out: &mut Vec<u8>, values: &[f64]| {
        u32_at(out, values.len() as u32);
        for v in values {
            while (out.len() - 4) % 8 != 0 {
                out.push(0);
            }
            out.extend(if big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            });
        }
    };
    u32_at(&mut out, sec as u32);
    u32_at(&mut out, nanosec);
    string(&mut out, "enc");
    u32_at(&mut out, names.len() as u32);
    for name in names {
        string(&mut out, name);
    }
    f64_seq(&mut out, position);
    f64_seq(&mut out, &[]);
    f64_seq(&mut out, &[0.5]);
    out
}

/// The mcap_messages input for `payloads` (see that target).
fn messages(flags: u8, layout: u8, payloads: &[Vec<u8>]) -> Vec<u8> {
    let mut out = vec![flags, layout];
    for p in payloads {
        out.extend((p.len() as u16).to_le_bytes());
        out.extend(p);
    }
    out
}

fn write(target: &str, name: &str, data: &[u8]) {
    let dir = Path::new("corpus").join(target);
    std::fs::create_dir_all(&dir).expect("corpus folder");
    std::fs::write(dir.join(name), data).expect("seed");
}

fn with_flags(flags: u8, data: &[u8]) -> Vec<u8> {
    let mut out = vec![flags];
    out.extend(data);
    out
}

fn main() {
    let testdata = Path::new("../testdata");
    let read = |p: &str| std::fs::read(testdata.join(p)).expect("testdata file");

    // CSV logs.
    write(
        "csv_reader",
        "small",
        &with_flags(0, &read("csv/small.csv")),
    );
    write(
        "csv_reader",
        "rad_unordered",
        &with_flags(0x0a, b"t,x\n0,1\n0,2\n-1,3e-3\n"),
    );
    write(
        "csv_reader",
        "quoted_crlf",
        &with_flags(4, b"\"t\",\"a b\",session\r\n1.5,\"2\",7\r\n2.5,-inf,1\r\n"),
    );
    let truth = read("examples/quick.truth/a.csv");
    write(
        "csv_reader",
        "table_as_log",
        &with_flags(1, &truth[..truth.len().min(600)]),
    );

    // MCAP files: the Python-written fixture (JointState + JSON + a foreign topic, zstd chunks),
    // and small uncompressed files written here, chunked and not.
    write(
        "mcap_reader",
        "fixture",
        &with_flags(0, &read("mcap/fixture.mcap")),
    );
    let js: Vec<Vec<u8>> = (0..6)
        .map(|i| {
            joint_state(
                1_700_000_000 + i,
                5_000_000,
                &["a", "b"],
                &[0.1 * i as f64, -0.2],
                i % 2 == 1,
            )
        })
        .collect();
    let json: Vec<Vec<u8>> = (0..6)
        .map(|i| {
            format!(
                "{{\"ref\": {}, \"note\": \"x\", \"b\": [1]}}",
                i as f64 * 0.25
            )
            .into_bytes()
        })
        .collect();
    let interleaved: Vec<Vec<u8>> = js
        .iter()
        .zip(&json)
        .flat_map(|(a, b)| [a.clone(), b.clone()])
        .collect();
    let slices = |v: &[Vec<u8>]| -> Vec<Vec<u8>> { v.to_vec() };
    for (name, layout, payloads) in [
        ("cdr_unchunked", 0u8, slices(&js)),
        ("cdr_chunked", 2, slices(&js)),
        ("json_unchunked", 1, slices(&json)),
        ("joined_chunked", 6, interleaved.clone()),
    ] {
        let refs: Vec<&[u8]> = payloads.iter().map(Vec::as_slice).collect();
        let file = wrap_messages(&Layout::from_byte(layout), &refs);
        write("mcap_reader", name, &with_flags(0, &file));
        write("mcap_messages", name, &messages(0, layout, &payloads));
    }
    write(
        "mcap_messages",
        "zero_stamp",
        &messages(0, 0, &[joint_state(0, 0, &["a"], &[1.0], false)]),
    );

    // A field read by path through its definition: a header, a nested array and the field.
    let definition = "std_msgs/Header header\nfloat64 position\nfuzz_msgs/Extra[] extra\n\
        ================================================================================\n\
        MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
        ================================================================================\n\
        MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\
        ================================================================================\n\
        MSG: fuzz_msgs/Extra\nstring name\nfloat32 value\n";
    let probe = |i: u32| {
        let mut out = vec![0, 1, 0, 0];
        out.extend(1i32.to_le_bytes());
        out.extend((i * 10_000_000).to_le_bytes());
        out.extend(2u32.to_le_bytes());
        out.extend(b"m\0");
        out.extend([0, 0]);
        out.extend((0.01 * f64::from(i)).to_le_bytes());
        out.extend(1u32.to_le_bytes());
        out.extend(2u32.to_le_bytes());
        out.extend(b"x\0");
        out.extend([0, 0]);
        out.extend((0.5f32 * i as f32).to_le_bytes());
        out
    };
    for (name, path) in [("position", "position"), ("nested", "extra[0].value")] {
        let mut input = vec![0];
        input.extend(definition.as_bytes());
        input.push(0);
        input.extend(path.as_bytes());
        input.push(0);
        for i in 0..4 {
            let payload = probe(i);
            input.extend((payload.len() as u16).to_le_bytes());
            input.extend(payload);
        }
        write("msgdef", name, &input);
    }

    // ROS 1 bags: JointState and scalars in chunks of each compression, indexed and not (the
    // layout byte of `ros1_reader`), and a small whole bag as the raw file.
    let mut rows = Vec::new();
    for i in 0..8u64 {
        let t = 1_700_000_000_000_000_000 + i * 5_000_000;
        let (topic, payload) = match i % 4 {
            3 => (1u8, (0.01 * i as f64).to_le_bytes().to_vec()),
            2 if i == 2 => (2, b"\x02\0\0\0hi".to_vec()),
            _ => (
                0,
                calib_fuzz::ros1_joint_state(i as u32, t, &["a", "b"], &[0.1 * i as f64, -0.2]),
            ),
        };
        rows.push((topic as usize, t, payload));
    }
    for (name, layout) in [
        ("none", 1u8 | (2 << 3)),
        ("bz2", 2 | (3 << 3)),
        ("lz4_unindexed", 3 | 4 | (1 << 3)),
    ] {
        let mut input = vec![0, layout];
        for (topic, t, payload) in &rows {
            input.push(*topic as u8);
            input.extend(t.to_le_bytes());
            input.extend((payload.len() as u16).to_le_bytes());
            input.extend(payload);
        }
        write("ros1_reader", name, &input);
    }
    let refs: Vec<(usize, u64, &[u8])> = rows
        .iter()
        .map(|(k, t, p)| (*k, *t, p.as_slice()))
        .collect();
    let bag = calib_fuzz::ros1_bag(&refs, 3, calib_fuzz::Ros1Compression::Lz4, true);
    write("ros1_reader", "raw_lz4", &[&[0u8, 0][..], &bag].concat());

    // Shift-angle readings: the test data, and a small complete set for 3 faces.
    write(
        "readings",
        "paper",
        &with_flags(0, &read("shift-angle/readings.csv")),
    );
    let mut small = String::from("shift_deg,start_face,step,reading_arcsec\n");
    for (s, shift) in [0.0, 120.0].iter().enumerate() {
        for j in 1..=3 {
            for i in 1..=3 {
                small.push_str(&format!("{shift},{j},{i},{}\n", (s + i * j) as f64 * 0.5));
            }
        }
    }
    write("readings", "three_faces", &with_flags(3, small.as_bytes()));

    // Budgets.
    write("budget", "table3", &read("shift-angle/table3.toml"));
    write("budget", "derived", &read("shift-angle/derived.toml"));

    // Correction tables, with and without uncertainties.
    let mut grid = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for i in 0..36 {
        let e = (i as f64 * 10f64.to_radians()).sin() * 3.0;
        grid.push_str(&format!("{:.6},{e:.6},{:.6}\n", i as f64 * 10.0, -e));
    }
    write("table", "grid36", grid.as_bytes());
    write("table", "four_points_u", b"angle_deg,error_arcsec,correction_arcsec,u_arcsec\n0,1.5,-1.5,0.1\n90,-0.5,0.5,0.1\n180,0.25,-0.25,0.2\n270,-1.25,1.25,0\n");
    write(
        "table",
        "reordered",
        b"correction_arcsec,angle_deg,error_arcsec\n-1,0.000000,1\n1,180.000000,-1\n",
    );

    // HDF5 (byte 1: 0 = a `.h5` file) and MATLAB v7.3 (byte 1: 1 = the input after a v7.3
    // header), and Parquet: the small fixtures h5py and pyarrow wrote.
    let shapes = read("hdf5/shapes.h5");
    write("hdf5_reader", "shapes_h5", &with_flags(0, &with_flags(0, &shapes)));
    let mat = read("hdf5/quick_v73.mat");
    write("hdf5_reader", "v73_body", &with_flags(0, &with_flags(1, &mat[512..])));
    write("parquet_reader", "shapes", &with_flags(0, &read("parquet/shapes.parquet")));
    write("parquet_reader", "int96", &with_flags(0, &read("parquet/legacy.parquet")));
}
