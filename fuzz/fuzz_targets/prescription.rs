#![no_main]
fts_fuzz::target!(prescription);
