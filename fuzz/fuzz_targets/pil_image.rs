#![no_main]
fts_fuzz::target!(pil_image);
