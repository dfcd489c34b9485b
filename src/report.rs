//! A report as a list of blocks, written as Markdown (`report.md`, images beside it) and as
//! self-contained HTML (`report.html`, images embedded as data URIs, no script, no network).

use base64::Engine;
use std::path::{Path, PathBuf};

/// One piece of a report.
#[derive(Debug, Clone, PartialEq)]
pub enum Block {
    /// A heading of level 1-3.
    Heading(u8, String),
    /// A paragraph (plain text; `code` spans in backquotes are kept).
    Text(String),
    /// A Markdown table (`| a | b |` lines, the second one the separator).
    Table(String),
    /// An image file in the report folder, with a caption.
    Image(PathBuf, String),
    /// Preformatted text (commands).
    Code(String),
}

/// A report under construction.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Document {
    /// Its blocks, in order.
    pub blocks: Vec<Block>,
}

/// A report could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {source}")]
pub struct ReportError {
    /// The file.
    pub path: PathBuf,
    /// The I/O error.
    pub source: std::io::Error,
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Inline `code` spans of escaped text.
fn inline(s: &str) -> String {
    escape(s)
        .split('`')
        .enumerate()
        .map(|(k, part)| {
            if k % 2 == 1 {
                format!("<code>{part}</code>")
            } else {
                part.to_string()
            }
        })
        .collect()
}

fn cells(line: &str) -> Vec<&str> {
    let t = line.trim().trim_start_matches('|').trim_end_matches('|');
    t.split('|').map(str::trim).collect()
}

fn mime(path: &Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()) {
        Some("gif") => "image/gif",
        Some("svg") => "image/svg+xml",
        _ => "image/png",
    }
}

impl Document {
    /// Appends a block.
    pub fn push(&mut self, block: Block) -> &mut Self {
        self.blocks.push(block);
        self
    }

    /// Markdown; image paths are relative to `dir` (the report folder).
    pub fn markdown(&self, dir: &Path) -> String {
        let mut out = String::new();
        for b in &self.blocks {
            match b {
                Block::Heading(level, text) => {
                    out += &format!("{} {text}\n\n", "#".repeat(usize::from(*level)));
                }
                Block::Text(text) => out += &format!("{text}\n\n"),
                Block::Table(table) => out += &format!("{}\n\n", table.trim_end()),
                Block::Image(path, caption) => {
                    let rel = path.strip_prefix(dir).unwrap_or(path);
                    out += &format!("![{caption}]({})\n\n*{caption}*\n\n", rel.display());
                }
                Block::Code(code) => out += &format!("```sh\n{}\n```\n\n", code.trim_end()),
            }
        }
        out
    }

    /// Self-contained HTML: every image read and embedded.
    pub fn html(&self, title: &str) -> Result<String, ReportError> {
        let mut body = String::new();
        for b in &self.blocks {
            match b {
                Block::Heading(level, text) => {
                    body += &format!("<h{level}>{}</h{level}>\n", inline(text));
                }
                Block::Text(text) => body += &format!("<p>{}</p>\n", inline(text)),
                Block::Table(table) => {
                    body += "<table>\n";
                    for (k, line) in table
                        .lines()
                        .filter(|l| l.trim_start().starts_with('|'))
                        .enumerate()
                    {
                        if k == 1 {
                            continue; // the separator row
                        }
                        let tag = if k == 0 { "th" } else { "td" };
                        let row: String = cells(line)
                            .iter()
                            .map(|c| format!("<{tag}>{}</{tag}>", inline(c)))
                            .collect();
                        body += &format!("<tr>{row}</tr>\n");
                    }
                    body += "</table>\n";
                }
                Block::Image(path, caption) => {
                    let bytes = std::fs::read(path).map_err(|source| ReportError {
                        path: path.clone(),
                        source,
                    })?;
                    let data = base64::engine::general_purpose::STANDARD.encode(bytes);
                    body += &format!(
                        "<figure><img src=\"data:{};base64,{data}\" alt=\"{}\"><figcaption>{}</figcaption></figure>\n",
                        mime(path),
                        escape(caption),
                        inline(caption)
                    );
                }
                Block::Code(code) => body += &format!("<pre>{}</pre>\n", escape(code)),
            }
        }
        Ok(format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>\n\
             body {{ font-family: sans-serif; max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #222; }}\n\
             table {{ border-collapse: collapse; margin: 1em 0; }}\n\
             th, td {{ border: 1px solid #bbb; padding: 4px 10px; text-align: right; }}\n\
             th:first-child, td:first-child {{ text-align: left; }}\n\
             img {{ max-width: 100%; border: 1px solid #ddd; }}\n\
             figure {{ margin: 1em 0; }} figcaption {{ color: #555; font-size: 90%; }}\n\
             pre {{ background: #f4f4f4; padding: 0.8em; overflow-x: auto; }}\n\
             code {{ background: #f4f4f4; padding: 0 3px; }}\n</style>\n</head>\n<body>\n{body}</body>\n</html>\n",
            escape(title)
        ))
    }

    /// Writes `report.md` and `report.html` (titled `title`) into `dir`, each atomically;
    /// returns their paths.
    pub fn write(&self, dir: &Path, title: &str) -> Result<(PathBuf, PathBuf), ReportError> {
        let md = dir.join("report.md");
        let html = dir.join("report.html");
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| ReportError { path, source }
        };
        crate::atomic::write(&md, self.markdown(dir)).map_err(io(&md))?;
        crate::atomic::write(&html, self.html(title)?).map_err(io(&html))?;
        Ok((md, html))
    }
}
