//! Bounds-checked reading of glTF accessors (strided views, normalised integers, sparse
//! substitution) for [`GltfDoc`]. Nothing is allocated from an unchecked count.

use gltf::accessor::{DataType, Dimensions};

use super::IoError;
use super::gltf_doc::GltfDoc;

/// Largest number of values an accessor without a buffer view may expand to.
const MAX_IMPLICIT_VALUES: usize = 1 << 24;

impl GltfDoc {
    /// The bytes of a buffer view, bounds-checked.
    fn view_bytes(&self, view: &gltf::buffer::View, what: &str) -> Result<&[u8], IoError> {
        let buffer = self
            .buffers
            .get(view.buffer().index())
            .ok_or_else(|| self.invalid(format!("{what}: missing buffer")))?;
        view.offset()
            .checked_add(view.length())
            .and_then(|end| buffer.get(view.offset()..end))
            .ok_or_else(|| {
                self.invalid(format!(
                    "{what}: buffer view {} (bytes {}..+{}) is out of range of buffer {} ({} bytes)",
                    view.index(),
                    view.offset(),
                    view.length(),
                    view.buffer().index(),
                    buffer.len()
                ))
            })
    }

    /// Checked sub-slice holding `count` elements of `elem` bytes every `stride` bytes from `offset`.
    fn strided<'b>(
        &self,
        data: &'b [u8],
        offset: usize,
        count: usize,
        elem: usize,
        stride: usize,
        what: &str,
    ) -> Result<&'b [u8], IoError> {
        if count == 0 {
            return Ok(&[]);
        }
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|v| v.checked_add(elem))
            .and_then(|v| v.checked_add(offset));
        end.and_then(|end| data.get(offset..end))
            .ok_or_else(|| self.invalid(format!("{what}: {count} elements of {elem} bytes from byte {offset} run past the buffer view ({} bytes)", data.len())))
    }

    /// Reads accessor `acc` as `f32` values (normalised integers scaled to [0, 1] / [-1, 1]),
    /// flattened, checking that it has `dims` components. Non-finite floats are errors.
    pub fn read_f32(
        &self,
        acc: &gltf::Accessor,
        dims: usize,
        what: &str,
    ) -> Result<Vec<f32>, IoError> {
        let what = format!("{what} (accessor {})", acc.index());
        let found = dims_of(acc.dimensions());
        if found != dims {
            return Err(self.invalid(format!(
                "{what}: {found} components per element, expected {dims}"
            )));
        }
        let ty = acc.data_type();
        let norm = acc.normalized();
        let decode = move |b: &[u8]| -> f32 {
            match ty {
                DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
                DataType::U16 if norm => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
                DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32,
                DataType::I16 if norm => {
                    (i16::from_le_bytes([b[0], b[1]]) as f32 / 32767.0).max(-1.0)
                }
                DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f32,
                DataType::U8 if norm => b[0] as f32 / 255.0,
                DataType::U8 => b[0] as f32,
                DataType::I8 if norm => (b[0] as i8 as f32 / 127.0).max(-1.0),
                DataType::I8 => b[0] as i8 as f32,
            }
        };
        let values = self.read_generic(acc, dims, &what, decode)?;
        if values.iter().any(|v| !v.is_finite()) {
            return Err(IoError::NonFinite {
                what,
                path: self.path.clone(),
            });
        }
        Ok(values)
    }

    /// Reads accessor `acc` as unsigned integers (indices, joint indices), checking `dims`.
    pub fn read_u32(
        &self,
        acc: &gltf::Accessor,
        dims: usize,
        what: &str,
    ) -> Result<Vec<u32>, IoError> {
        let what = format!("{what} (accessor {})", acc.index());
        let found = dims_of(acc.dimensions());
        if found != dims {
            return Err(self.invalid(format!(
                "{what}: {found} components per element, expected {dims}"
            )));
        }
        let ty = acc.data_type();
        if !matches!(ty, DataType::U8 | DataType::U16 | DataType::U32) || acc.normalized() {
            return Err(self.invalid(format!(
                "{what}: component type {ty:?} is not an unsigned integer"
            )));
        }
        self.read_generic(acc, dims, &what, move |b: &[u8]| match ty {
            DataType::U8 => b[0] as u32,
            DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as u32,
            _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        })
    }

    fn read_generic<T: Copy + Default>(
        &self,
        acc: &gltf::Accessor,
        dims: usize,
        what: &str,
        decode: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, IoError> {
        let comp = acc.data_type().size();
        let elem = comp * dims;
        let count = acc.count();
        let mut out: Vec<T> = match acc.view() {
            Some(view) => {
                let data = self.view_bytes(&view, what)?;
                let stride = view.stride().unwrap_or(elem);
                if stride < elem {
                    return Err(self.invalid(format!(
                        "{what}: byte stride {stride} is smaller than an element ({elem} bytes)"
                    )));
                }
                let bytes = self.strided(data, acc.offset(), count, elem, stride, what)?;
                let mut v = Vec::with_capacity(count * dims);
                for i in 0..count {
                    for k in 0..dims {
                        let at = i * stride + k * comp;
                        let Some(b) = bytes.get(at..at + comp) else {
                            return Err(self.invalid(format!("{what}: element {i} out of range")));
                        };
                        v.push(decode(b));
                    }
                }
                v
            }
            None => {
                if count.saturating_mul(dims) > MAX_IMPLICIT_VALUES {
                    return Err(
                        self.invalid(format!("{what}: {count} elements without a buffer view"))
                    );
                }
                vec![T::default(); count * dims]
            }
        };
        if let Some(sparse) = acc.sparse() {
            let n = sparse.count();
            let idx_view = sparse.indices().view();
            let idx_size = match sparse.indices().index_type() {
                gltf::accessor::sparse::IndexType::U8 => 1,
                gltf::accessor::sparse::IndexType::U16 => 2,
                gltf::accessor::sparse::IndexType::U32 => 4,
            };
            let idx_bytes = self.strided(
                self.view_bytes(&idx_view, what)?,
                sparse.indices().offset(),
                n,
                idx_size,
                idx_size,
                what,
            )?;
            let val_bytes = self.strided(
                self.view_bytes(&sparse.values().view(), what)?,
                sparse.values().offset(),
                n,
                elem,
                elem,
                what,
            )?;
            for s in 0..n {
                let ib = idx_bytes
                    .get(s * idx_size..(s + 1) * idx_size)
                    .unwrap_or(&[]);
                let index = match ib.len() {
                    1 => ib[0] as usize,
                    2 => u16::from_le_bytes([ib[0], ib[1]]) as usize,
                    4 => u32::from_le_bytes([ib[0], ib[1], ib[2], ib[3]]) as usize,
                    _ => return Err(self.invalid(format!("{what}: sparse index {s} out of range"))),
                };
                if index >= count {
                    return Err(
                        self.invalid(format!("{what}: sparse index {index} >= count {count}"))
                    );
                }
                for k in 0..dims {
                    let at = s * elem + k * comp;
                    let (Some(b), Some(slot)) =
                        (val_bytes.get(at..at + comp), out.get_mut(index * dims + k))
                    else {
                        return Err(self.invalid(format!("{what}: sparse value {s} out of range")));
                    };
                    *slot = decode(b);
                }
            }
        }
        Ok(out)
    }
}

/// Components per element of an accessor type.
fn dims_of(d: Dimensions) -> usize {
    match d {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 | Dimensions::Mat2 => 4,
        Dimensions::Mat3 => 9,
        Dimensions::Mat4 => 16,
    }
}
