//! fts-servo `daq-io` (filled by its own issue).
