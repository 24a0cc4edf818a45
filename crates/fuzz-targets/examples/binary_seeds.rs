//! Writes the seeds of the fuzz targets whose inputs are made by our libraries rather than by
//! the `servo` command (`scripts/fuzz_seeds.sh` runs it): deployment images and link sessions,
//! a plant file, sag grids, live-view client frames.
//!
//! Usage: `cargo run -p fuzz-targets --example binary_seeds -- SEEDS_DIR DEPLOYMENT.toml...`
//! (the images and link sessions are made from the deployment files `servo deploy` wrote).

use live_view::ws::protocol::opcode;
use servo_config::Deployment;
use servo_link::{image, kind, write_frame, Boot, Ready, Report, TickReply};
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((out, deployments)) = args.split_first() else {
        panic!("usage: binary_seeds SEEDS_DIR DEPLOYMENT.toml...");
    };
    let out = Path::new(out);
    let write = |target: &str, name: &str, bytes: &[u8]| {
        let dir = out.join(target);
        std::fs::create_dir_all(&dir).expect("a writable seeds folder");
        std::fs::write(dir.join(name), bytes).expect("a writable seed");
    };
    for file in deployments {
        let path = Path::new(file);
        let text = std::fs::read_to_string(path).expect("a readable deployment file");
        let origin = servo_config::Origin::default();
        let d = servo_config::parse_deployment(&text, &origin)
            .expect("a deployment servo deploy wrote")
            .deployment;
        let d = &d;
        let name = path.file_stem().expect("a file name").to_string_lossy();
        let mut img = vec![0u8; image::MAX_BYTES];
        let n = image::encode(d, &mut img).expect("the prototype fits an image");
        img.truncate(n);
        write("pil_image", &format!("{name}.img"), &img);
        let (stream, records) = session(d, &img);
        write(
            "pil_link",
            &format!("{name}-stream.bin"),
            &[&[0], &stream[..]].concat(),
        );
        write(
            "pil_link",
            &format!("{name}-frames.bin"),
            &[&[1], &records[..]].concat(),
        );
    }
    write(
        "plant_file",
        "prototype.toml",
        run_config::plant_toml(&plant_sim::PlantParams::default()).as_bytes(),
    );
    write(
        "sag_grid",
        "bump-4x4.csv",
        b"# z in mm\n0,0,0,0\n0,0.001,0.001,0\n0,0.001,0.001,0\n0,0,0,0\n",
    );
    let mut bowl = String::from("# 9 x 9 nodes, mm\n");
    for i in -4i32..=4 {
        let row: Vec<String> = (-4i32..=4)
            .map(|j| format!("{:e}", 1e-4 * f64::from(i * i + j * j) / 32.0))
            .collect();
        bowl.push_str(&row.join(","));
        bowl.push('\n');
    }
    write("sag_grid", "bowl-9x9.csv", bowl.as_bytes());
    write("live_view", "session.bin", &client_session());
}

/// A processor-in-the-loop session as both ends send it: boot, load, ready, three samples with
/// the loop's replies, the report — as the byte stream, and as the records (kind, length,
/// payload) the fuzz target frames itself.
fn session(d: &Deployment, img: &[u8]) -> (Vec<u8>, Vec<u8>) {
    let mut servo = servo_runtime::Servo::new(d).expect("the deployment builds");
    let (mut bytes, mut records) = (Vec::new(), Vec::new());
    let mut frame = |k: u8, payload: &[u8]| {
        assert!(write_frame(k, payload, |b| bytes.push(b)));
        records.push(k);
        records.extend_from_slice(&(payload.len() as u16).to_le_bytes());
        records.extend_from_slice(payload);
    };
    frame(kind::BOOT, &Boot::default().encode());
    frame(kind::LOAD, img);
    frame(kind::READY, &Ready::default().encode());
    for seq in 0..3u64 {
        let sample = daq_io::Sensor {
            seq,
            time_s: seq as f64 * 5.01e-6,
            gap_v: 0.01 * seq as f64,
            run_id: 1,
            ..daq_io::Sensor::default()
        };
        let mut s = [0; servo_link::SENSOR_BYTES];
        servo_link::encode_sensor(&sample, &mut s);
        frame(kind::SAMPLE, &s);
        let mut t = [0; servo_link::TICK_BYTES];
        TickReply {
            command: servo.tick(&sample),
            telemetry: None,
            trip: None,
            trip_settled: false,
            cost_counts: 1_200,
        }
        .encode(&mut t);
        frame(kind::TICK, &t);
    }
    frame(kind::REPORT_REQUEST, &[]);
    frame(kind::REPORT, &Report::default().encode());
    (bytes, records)
}

/// A client's frames (masked, as a client must send them): subscriptions, parameter requests,
/// a gain change, a service call, a ping and a close.
fn client_session() -> Vec<u8> {
    let mut bytes = Vec::new();
    let texts = [
        r#"{"op":"subscribe","subscriptions":[{"id":1,"channelId":1},{"id":2,"channelId":2}]}"#
            .to_string(),
        r#"{"op":"getParameters","parameterNames":[],"id":"all"}"#.to_string(),
        format!(
            r#"{{"op":"setParameters","parameters":[{{"name":"{}","value":0.9}}],"id":"g"}}"#,
            live_view::GAIN_SCALE
        ),
        r#"{"op":"subscribeParameterUpdates","parameterNames":["a"]}"#.to_string(),
        r#"{"op":"unsubscribe","subscriptionIds":[1]}"#.to_string(),
    ];
    for t in &texts {
        masked(&mut bytes, 0x1, t.as_bytes());
    }
    let mut call = vec![opcode::SERVICE_CALL_REQUEST];
    call.extend_from_slice(&1u32.to_le_bytes());
    call.extend_from_slice(&7u32.to_le_bytes());
    call.extend_from_slice(&4u32.to_le_bytes());
    call.extend_from_slice(b"json{}");
    masked(&mut bytes, 0x2, &call);
    masked(&mut bytes, 0x9, b"ping");
    masked(&mut bytes, 0x8, &1000u16.to_be_bytes());
    bytes
}

/// One final WebSocket frame of `op` carrying `payload`, masked with a fixed key.
fn masked(out: &mut Vec<u8>, op: u8, payload: &[u8]) {
    let key = [0x37, 0xfa, 0x21, 0x3d];
    out.push(0x80 | op);
    match payload.len() {
        n @ 0..=125 => out.push(0x80 | n as u8),
        n => {
            out.push(0x80 | 126);
            out.extend_from_slice(&(n as u16).to_be_bytes());
        }
    }
    out.extend_from_slice(&key);
    out.extend(payload.iter().enumerate().map(|(i, b)| b ^ key[i % 4]));
}
