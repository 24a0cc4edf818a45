//! fts-servo `plant-sim` (filled by its own issue).
