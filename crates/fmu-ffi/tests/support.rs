//! Units made in process for the tests and the bench: their resources written to a folder,
//! instantiated through the FMI functions.

#![allow(dead_code)] // each includer uses its part

use fmu::UnitFiles;
use fts_fmu::fmi2::fmi2Instantiate;
use fts_fmu::fmi3::fmi3InstantiateCoSimulation;
use fts_fmu::instance::Fmi3Logger;
use std::ffi::{c_void, CString};
use std::path::Path;

/// Writes `files`' resources into `dir` and returns the instantiation token.
pub fn resources(dir: &Path, files: &UnitFiles) -> String {
    std::fs::write(dir.join(fmu::UNIT_FILE), &files.unit).unwrap();
    if let Some(d) = &files.deployment {
        std::fs::write(dir.join(fmu::DEPLOYMENT_FILE), d).unwrap();
    }
    fmu::token(
        files.unit.as_bytes(),
        files.deployment.as_deref().map(str::as_bytes),
    )
}

pub fn fmi2_unit(dir: &Path, token: &str) -> *mut c_void {
    let uri = CString::new(format!("file://{}", dir.display())).unwrap();
    let token = CString::new(token).unwrap();
    // SAFETY: NUL-terminated strings; no callbacks.
    unsafe {
        fmi2Instantiate(
            c"u".as_ptr(),
            1,
            token.as_ptr(),
            uri.as_ptr(),
            std::ptr::null(),
            0,
            0,
        )
    }
}

pub fn fmi3_unit(dir: &Path, token: &str, log: Option<Fmi3Logger>) -> *mut c_void {
    let path = CString::new(format!("{}/", dir.display())).unwrap();
    let token = CString::new(token).unwrap();
    // SAFETY: NUL-terminated strings; `log` is NULL or reads the message only.
    unsafe {
        fmi3InstantiateCoSimulation(
            c"u".as_ptr(),
            token.as_ptr(),
            path.as_ptr(),
            false,
            false,
            false,
            false,
            std::ptr::null(),
            0,
            std::ptr::null_mut(),
            log,
            std::ptr::null(),
        )
    }
}
