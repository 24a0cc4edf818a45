//! Durability off the writer thread: `fdatasync` waits for the storage (≈ 14 ms per simulated
//! second of recording on this project's CI disk), so a thread of its own does it on a second
//! handle of the file while the writer goes on encoding and compressing.

use std::fs::File;
use std::io;
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

/// The sync thread of one recording.
pub(crate) struct Syncer {
    /// One pending request at most: asking while a sync is waiting is a no-op.
    request: SyncSender<()>,
    /// The first failed sync's error.
    error: Arc<Mutex<Option<io::Error>>>,
    thread: JoinHandle<()>,
}

impl Syncer {
    /// Starts the thread on a second handle of `file`.
    pub(crate) fn start(file: &File) -> io::Result<Self> {
        let file = file.try_clone()?;
        let (request, requests) = sync_channel::<()>(1);
        let error = Arc::new(Mutex::new(None));
        let failed = error.clone();
        let thread = std::thread::Builder::new()
            .name("mcap-sync".into())
            .spawn(move || {
                while requests.recv().is_ok() {
                    if let Err(e) = file.sync_data() {
                        *failed.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
                        break;
                    }
                }
            })?;
        Ok(Syncer {
            request,
            error,
            thread,
        })
    }

    /// Asks for a sync of everything written so far, without waiting for it; reports the
    /// error of an earlier sync, if one failed.
    pub(crate) fn request(&self) -> io::Result<()> {
        self.take_error()?;
        match self.request.try_send(()) {
            Ok(()) | Err(TrySendError::Full(())) => Ok(()),
            Err(TrySendError::Disconnected(())) => self
                .take_error()
                .and(Err(io::Error::other("the sync thread stopped"))),
        }
    }

    /// Waits for the thread to finish its last sync and reports any sync's error.
    pub(crate) fn stop(self) -> io::Result<()> {
        drop(self.request);
        let _ = self.thread.join();
        let error = self.error.lock().unwrap_or_else(|p| p.into_inner()).take();
        error.map_or(Ok(()), Err)
    }

    fn take_error(&self) -> io::Result<()> {
        let error = self.error.lock().unwrap_or_else(|p| p.into_inner()).take();
        error.map_or(Ok(()), Err)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn syncs_on_request_and_stops_cleanly() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("file");
        let mut file = File::create(&path).unwrap();
        let syncer = Syncer::start(&file).unwrap();
        file.write_all(b"data").unwrap();
        for _ in 0..3 {
            syncer.request().unwrap();
        }
        syncer.stop().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"data");
    }

    #[test]
    fn a_failed_sync_is_reported() {
        // A pipe cannot be synced (EINVAL): the error reaches the writer.
        let (reader, _writer) = std::io::pipe().unwrap();
        let file = File::from(std::os::fd::OwnedFd::from(reader));
        let syncer = Syncer::start(&file).unwrap();
        syncer.request().unwrap();
        assert!(syncer.stop().is_err());
    }
}
