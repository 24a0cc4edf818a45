#![no_main]
fts_fuzz::target!(c_abi_open_toml);
