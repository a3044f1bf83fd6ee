//! The formats that hold a whole stack in one file, told apart: a Bonn `.btf` file or a
//! zip of UBO2003/ATRIUM images, each opened as a lazy [`ImageSource`].

use crate::btf::source::ImageSource;
use crate::btf::Crop;
use crate::Result;
use std::path::Path;

/// The lazy source of a file that holds a whole stack (a Bonn `.btf` file or a zip of
/// UBO2003/ATRIUM images), restricted to `crop`; `None` if `path` is not such a file
/// (a directory, a manifest or one image, which [`crate::btf::load()`] reads).
pub fn open(path: &Path, crop: Option<Crop>) -> Result<Option<Box<dyn ImageSource>>> {
    if crate::btf::ubo2014::is_bonn_file(path) {
        let file = crate::btf::ubo2014::BonnBtf::open(path)?;
        return Ok(Some(Box::new(file.into_window(crop)?)));
    }
    if crate::btf::archive::is_zip(path) {
        return Ok(Some(Box::new(crate::btf::archive::ZipStack::open(path, crop)?)));
    }
    Ok(None)
}
