#![no_main]
fts_fuzz::target!(run_config);
