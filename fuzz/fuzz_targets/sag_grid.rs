#![no_main]
fts_fuzz::target!(sag_grid);
