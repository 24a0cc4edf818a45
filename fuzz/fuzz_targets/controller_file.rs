#![no_main]
fts_fuzz::target!(controller_file);
