#![no_main]
fts_fuzz::target!(live_view);
