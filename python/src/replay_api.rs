//! `replay`: a recording run again from what it holds, through the library call `servo replay`
//! makes, and compared with it.

use crate::servo_err;
use pyo3::prelude::*;
use run_config::read_plant_file;
use runner::recording::Target;
use runner::replay::Replay;
use runner::run::RunOptions;
use runner::stop::StopRequest;
use std::path::PathBuf;

/// Replays the recording at `file` (with `salvage`, as far as it is intact) — on the plant of
/// the plant file `plant` when given — recording the replay to `out` (None: not recorded), and
/// returns the report `servo replay --json` prints.
#[pyfunction]
#[pyo3(signature = (file, out=None, overwrite=false, plant=None, salvage=false))]
pub fn replay(
    py: Python<'_>,
    file: PathBuf,
    out: Option<PathBuf>,
    overwrite: bool,
    plant: Option<PathBuf>,
    salvage: bool,
) -> PyResult<String> {
    let report = py.detach(|| {
        let mut replay = Replay::open(&file, salvage).map_err(servo_err)?;
        if let Some(p) = &plant {
            replay.replace_plant(read_plant_file(p).map_err(servo_err)?);
        }
        let stop = StopRequest::new();
        let opts = RunOptions {
            out: out.map(|path| Target {
                overwrite,
                ..Target::new(path)
            }),
            stop: &stop,
            progress: &mut |_, _| {},
            digest: false,
        };
        replay.run(opts).map_err(servo_err)
    })?;
    serde_json::to_string(&report).map_err(servo_err)
}
