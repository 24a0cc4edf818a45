#![no_main]
fts_fuzz::target!(frf_csv);
