//! fts-servo `design` (filled by its own issue).
