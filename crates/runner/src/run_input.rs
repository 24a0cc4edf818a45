//! A run's input files: each is read once and travels in the recording, so a replay reads the
//! recording's copy and never the path.

use recorder::Input;

/// The bytes of the input file `name`: the recording's embedded copy from `inputs` when there,
/// else `read` and added to `inputs` (so a recording of the run carries it).
pub(crate) fn input_or_read<E>(
    inputs: &mut Vec<Input>,
    name: &str,
    media_type: &str,
    read: impl FnOnce() -> Result<Vec<u8>, E>,
) -> Result<Vec<u8>, E> {
    if let Some(i) = inputs.iter().find(|i| i.name == name) {
        return Ok(i.data.clone());
    }
    let data = read()?;
    inputs.push(Input {
        name: name.into(),
        media_type: media_type.into(),
        data: data.clone(),
    });
    Ok(data)
}
