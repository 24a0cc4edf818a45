#![no_main]
fts_fuzz::target!(plant_file);
