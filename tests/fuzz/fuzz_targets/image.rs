//! The checked image loader (every command that reads images): any bytes give a grey image or
//! an error naming the reason; never more than the pixel limit decoded.
#![no_main]

use ferrocal_vision::detect::{check_image_file, load_gray};
use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    let path = common::temp_file("image", data);
    let _ = check_image_file(&path);
    if let Ok(img) = load_gray(&path) {
        assert!(img.width() > 0 && img.height() > 0);
    }
});
