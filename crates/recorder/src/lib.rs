//! fts-servo `recorder` (filled by its own issue).
