//! Chunk compression off the writer's thread: a pool of zstd compressors that take a closed
//! chunk's records and give back its compressed frame and CRC-32, each job answered on its own
//! channel so the writer can collect them in the order it closed them (the file's bytes do not
//! depend on which compressor finishes first). The queue is bounded: a writer that closes
//! chunks faster than they are compressed waits.

use std::io;
use std::sync::mpsc::{self, Receiver, SyncSender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

/// A chunk's records in, its zstd frame and the records' CRC-32 out.
pub(crate) struct Job {
    /// The chunk's records (uncompressed).
    pub(crate) records: Vec<u8>,
    /// Their zstd frame, once done.
    pub(crate) compressed: Vec<u8>,
    /// CRC-32 of `records`, once done.
    pub(crate) crc: u32,
    /// How the compression went.
    pub(crate) result: io::Result<()>,
}

impl Job {
    /// A job for `records`, its output into `compressed` (a buffer to reuse).
    pub(crate) fn new(records: Vec<u8>, compressed: Vec<u8>) -> Self {
        Job {
            records,
            compressed,
            crc: 0,
            result: Ok(()),
        }
    }

    fn run(&mut self, zstd: &mut zstd::bulk::Compressor<'static>) {
        self.compressed.clear();
        self.compressed
            .reserve(zstd::zstd_safe::compress_bound(self.records.len()));
        self.result = zstd
            .compress_to_buffer(&self.records, &mut self.compressed)
            .map(|_| ());
        self.crc = crc32fast::hash(&self.records);
    }
}

/// A job on its way, and where its answer comes back.
type Request = (Job, SyncSender<Job>);

/// The pool.
pub(crate) struct Compressors {
    queue: Option<SyncSender<Request>>,
    threads: Vec<JoinHandle<()>>,
}

impl Compressors {
    /// `n` compressors at zstd `level`, each on a thread of its own, with a queue of `n` jobs.
    pub(crate) fn start(n: usize, level: i32) -> io::Result<Self> {
        let (queue, jobs) = mpsc::sync_channel::<Request>(n);
        let jobs = Arc::new(Mutex::new(jobs));
        let mut threads = Vec::with_capacity(n);
        for i in 0..n {
            let mut zstd = zstd::bulk::Compressor::new(level)?;
            let jobs = Arc::clone(&jobs);
            let thread = std::thread::Builder::new()
                .name(format!("fts-zstd-{i}"))
                .spawn(move || {
                    while let Some((mut job, answer)) = next(&jobs) {
                        job.run(&mut zstd);
                        // A writer that stopped waiting (it failed) drops its answers.
                        let _ = answer.send(job);
                    }
                })?;
            threads.push(thread);
        }
        Ok(Compressors {
            queue: Some(queue),
            threads,
        })
    }

    /// Queues `job` (waits while the queue is full); its answer comes on the receiver.
    pub(crate) fn submit(&self, job: Job) -> io::Result<Receiver<Job>> {
        let (answer, receiver) = mpsc::sync_channel(1);
        self.queue
            .as_ref()
            .expect("the queue lives as long as the pool")
            .send((job, answer))
            .map_err(|_| gone())?;
        Ok(receiver)
    }
}

/// The next request, None when the pool is shutting down.
fn next(jobs: &Mutex<Receiver<Request>>) -> Option<Request> {
    jobs.lock().unwrap_or_else(|e| e.into_inner()).recv().ok()
}

/// A compressor thread is gone (it can only have panicked).
pub(crate) fn gone() -> io::Error {
    io::Error::other("a chunk compressor stopped")
}

impl Drop for Compressors {
    fn drop(&mut self) {
        // Closing the queue ends every thread once it is drained.
        self.queue = None;
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
