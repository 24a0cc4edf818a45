//! The study's table as Apache Parquet (what pandas, polars, Arrow and Spark read without a
//! schema of ours): the same columns as the CSV — `index` (INT64), `controller`, `status` and
//! `reason` (UTF-8), the parameters and metrics as DOUBLE, `controller_states` as INT64 — with
//! a failed point's metrics and reason-less rows as nulls, and the study's description and
//! SHA-256 in the file's key-value metadata.

use super::evaluate::Point;
use super::spec::Study;
use super::table::metric_columns;
use crate::report::ReportError;
use parquet::basic::{LogicalType, Repetition, Type as Physical};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::{Type, TypePtr};
use std::path::Path;
use std::sync::Arc;

/// Rows per row group.
const ROW_GROUP: usize = 1 << 20;

/// Metadata key of the study's description.
pub const STUDY_KEY: &str = "fts_servo.study";
/// Metadata key of the description's SHA-256.
pub const STUDY_SHA_KEY: &str = "fts_servo.study_sha256";

/// One column's values for a slice of rows.
enum Column {
    Int(Vec<Option<i64>>),
    Text(Vec<Option<String>>),
    Double(Vec<Option<f64>>),
}

fn field(name: &str, physical: Physical, optional: bool, text: bool) -> TypePtr {
    let mut b = Type::primitive_type_builder(name, physical).with_repetition(if optional {
        Repetition::OPTIONAL
    } else {
        Repetition::REQUIRED
    });
    if text {
        b = b.with_logical_type(Some(LogicalType::String));
    }
    Arc::new(b.build().expect("a valid primitive column"))
}

/// The columns of `rows`, in the CSV's order, with their schema fields.
fn columns(study: &Study, rows: &[Point]) -> Vec<(TypePtr, Column)> {
    let mut out = vec![
        (
            field("index", Physical::INT64, false, false),
            Column::Int(rows.iter().map(|p| Some(p.index as i64)).collect()),
        ),
        (
            field("controller", Physical::BYTE_ARRAY, false, true),
            Column::Text(rows.iter().map(|p| Some(p.family.name().into())).collect()),
        ),
    ];
    for (j, par) in study.table.parameters.iter().enumerate() {
        out.push((
            field(&par.key, Physical::DOUBLE, false, false),
            Column::Double(rows.iter().map(|p| Some(p.values[j])).collect()),
        ));
    }
    out.push((
        field("status", Physical::BYTE_ARRAY, false, true),
        Column::Text(
            rows.iter()
                .map(|p| Some(if p.outcome.is_ok() { "ok" } else { "failed" }.into()))
                .collect(),
        ),
    ));
    out.push((
        field("reason", Physical::BYTE_ARRAY, true, true),
        Column::Text(rows.iter().map(|p| p.outcome.clone().err()).collect()),
    ));
    let metrics: Vec<Option<Vec<f64>>> = rows
        .iter()
        .map(|p| p.outcome.as_ref().ok().map(|m| m.columns()))
        .collect();
    for (k, name) in metric_columns().iter().enumerate() {
        let value = |m: &Option<Vec<f64>>| m.as_ref().map(|v| v[k]).filter(|v| !v.is_nan());
        out.push(if name == "controller_states" {
            (
                field(name, Physical::INT64, true, false),
                Column::Int(metrics.iter().map(|m| value(m).map(|v| v as i64)).collect()),
            )
        } else {
            (
                field(name, Physical::DOUBLE, true, false),
                Column::Double(metrics.iter().map(value).collect()),
            )
        });
    }
    out
}

/// Present values and definition levels of an optional column.
fn split<T: Clone>(v: &[Option<T>]) -> (Vec<T>, Vec<i16>) {
    let levels = v.iter().map(|x| i16::from(x.is_some())).collect();
    (v.iter().flatten().cloned().collect(), levels)
}

/// Writes `points` (in index order) of `study` as `path`.
pub fn write(study: &Study, points: &[Point], path: &Path) -> Result<(), ReportError> {
    let fail = |e: parquet::errors::ParquetError| ReportError::Io {
        path: path.to_owned(),
        source: std::io::Error::other(e.to_string()),
    };
    let fields: Vec<TypePtr> = columns(study, &[]).into_iter().map(|(f, _)| f).collect();
    let schema = Arc::new(
        Type::group_type_builder("study")
            .with_fields(fields)
            .build()
            .map_err(fail)?,
    );
    let props = WriterProperties::builder()
        .set_key_value_metadata(Some(vec![
            KeyValue::new(STUDY_KEY.into(), study.text.clone()),
            KeyValue::new(STUDY_SHA_KEY.into(), study.sha256.clone()),
        ]))
        .set_created_by(concat!("fts-servo ", env!("CARGO_PKG_VERSION")).into())
        .build();
    let file = std::fs::File::create(path).map_err(|source| ReportError::Io {
        path: path.to_owned(),
        source,
    })?;
    let mut writer = SerializedFileWriter::new(file, schema, Arc::new(props)).map_err(fail)?;
    for rows in points.chunks(ROW_GROUP) {
        let mut group = writer.next_row_group().map_err(fail)?;
        for (_, column) in columns(study, rows) {
            let mut col = group
                .next_column()
                .map_err(fail)?
                .expect("one writer per schema column");
            match column {
                Column::Int(v) => {
                    let (values, levels) = split(&v);
                    col.typed::<Int64Type>()
                        .write_batch(&values, Some(&levels), None)
                }
                Column::Double(v) => {
                    let (values, levels) = split(&v);
                    col.typed::<DoubleType>()
                        .write_batch(&values, Some(&levels), None)
                }
                Column::Text(v) => {
                    let (values, levels) = split(&v);
                    let bytes: Vec<ByteArray> = values
                        .into_iter()
                        .map(|s| ByteArray::from(s.into_bytes()))
                        .collect();
                    col.typed::<ByteArrayType>()
                        .write_batch(&bytes, Some(&levels), None)
                }
            }
            .map_err(fail)?;
            col.close().map_err(fail)?;
        }
        group.close().map_err(fail)?;
    }
    writer.close().map_err(fail)?;
    Ok(())
}
