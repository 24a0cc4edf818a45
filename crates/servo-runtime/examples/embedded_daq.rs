//! A DAQ daemon embedding the controller: each tick it reads the ADC, runs the servo and writes
//! the DAC in its own loop — no IPC on the servo path. `serve` publishes telemetry and health
//! and answers `servo ctl` (gain, load, stop) from a thread of its own, so `servo record`,
//! `servo view` and the Python tap work against it. The "hardware" here is the simulated stage.
//!
//! ```text
//! servo deploy -o deploy.toml
//! cargo run --release -p servo-runtime --features serve --example embedded_daq -- deploy.toml lab 10
//! ```
use daq_io::{clock::monotonic_ns, clock::Wait, Sensor};
use plant_sim::{PlantParams, Simulator};
use servo_runtime::Servo;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (file, prefix, seconds): (&str, &str, f64) = (&args[1], &args[2], args[3].parse()?);
    let mut servo = Servo::from_file(file)?;
    servo.serve(prefix)?;
    let mut stage = Simulator::new(&PlantParams::default(), 1, &Default::default())?; // your ADC/DAC
    let period_ns = (servo.period_s() * 1e9).round() as u64;
    let start_ns = monotonic_ns() + period_ns;
    let mut sample = Sensor {
        run_id: daq_io::peers::random_id(),
        ..Default::default()
    };
    for k in 0..(seconds / servo.period_s()).round() as u64 {
        let deadline_ns = start_ns + k * period_ns;
        Wait::Spin.until(deadline_ns);
        (sample.seq, sample.published_ns) = (k, deadline_ns);
        let command = servo.tick(&sample); // no allocation, lock, log or panic
        let (reading, _) = stage.step(command.dac_v); // write the DAC; the ADC at the tick's end
        (sample.time_s, sample.gap_v, sample.accel_v) =
            (reading.time_s, reading.gap_v, reading.accel_v);
        sample.flags = reading.flags;
        if servo.status().stop.is_some() {
            break;
        }
    }
    servo.close(0);
    let (status, timing) = (servo.status(), servo.timing());
    let end = match (status.stop, status.trip) {
        (Some(daq_io::stop_cause::CONTROL), _) => "stopped by the control plane".to_owned(),
        (_, Some(trip)) => format!("tripped ({}) at tick {}", trip.cause.name(), trip.tick),
        _ => "ran its time".to_owned(),
    };
    println!(
        "{} ticks at output scale {}, {end}",
        status.ticks, status.gain_scale
    );
    println!(
        "  start lateness p99.99 {:.1} µs, execution p99.99 {:.2} µs, {} overruns",
        timing.lateness.p9999_ns as f64 * 1e-3,
        timing.execution.p9999_ns as f64 * 1e-3,
        status.overruns
    );
    Ok(())
}
