//! The interpreter fed from a file read a piece at a time, O-word jumps included
//! (docs/performance.md, "Streaming"), as LinuxCNC's interpreter reads its file line by line and
//! seeks back to the labels it remembers.
//!
//! - **The first reading** goes through the file once, a piece of about `chunk_bytes` at a time,
//!   cut at line breaks. Each piece is parsed ([`ChunkParser`]: every parse diagnostic is
//!   reported here), and each O-word statement in it is fed to the control-flow analysis
//!   ([`flow`](super::flow)) and indexed: its block index in the file with the byte offset, line
//!   number and text offset of its line. The index holds one entry per O-word statement, never
//!   one per line.
//! - **The run** is the whole-program interpreter's own loop ([`Interp::run_piece`]), run over the
//!   piece that holds the next block. When the run goes on outside the piece, the piece holding
//!   the block is taken from a small cache of parsed pieces, or read again: from the end of a
//!   cached piece when the run goes on after it, else from the indexed line of the O-word
//!   statement the jump leads to (or follows). A subroutine's body is read up to its `endsub`.
//!   The run reaches an O-word statement whose partners lie beyond the first reading (an `if`
//!   whose `else` has not been read, a call of a subroutine defined further on) only after the
//!   first reading has gone far enough to know them ([`Flow::resolved`]).
//! - **Diagnostics** are those of the whole program: the parser's, then, if the analysis of the
//!   whole file finds an error, the analysis' (nothing has then run, as for a whole program), or
//!   else the run's. Parsing a piece again reports nothing again.
//!
//! Memory: the pieces being read and cached (a few times `chunk_bytes`), the moves not handed on
//! yet (at most [`YIELD_MOVES`] and the last one), the interpreter's state, and per O-word
//! statement of the file its index entry and jump (about 100 bytes: a program with millions of
//! O-word statements holds them all).

use std::borrow::Cow;
use std::collections::{BTreeMap, VecDeque};
use std::io::{BufRead, Seek, SeekFrom};

use super::flow::{Analyser, Flow, Jump};
use super::{
    Carry, Exit, Interp, InterpOptions, Move, Next, Toolpath, after_end, conclude, has_code,
    no_end_warning,
};
use crate::Error;
use crate::diag::{Diagnostic, Sink, Span};
use crate::syntax::{ChunkParser, ParseOptions, Program};

/// A program's bytes, readable from any offset: a file, or a string in memory.
pub trait ProgramRead: BufRead + Seek {}

impl<T: BufRead + Seek + ?Sized> ProgramRead for T {}

/// The moves are handed on whenever this many are waiting (a loop that never leaves its piece
/// would otherwise hold all it makes).
pub const YIELD_MOVES: usize = 4096;

/// Most pieces kept parsed for jumps back.
const CACHE_PIECES: usize = 8;

/// Where a line starts: byte offset in the file, lines before it, offset in the text as parsed
/// (the file's bytes with invalid UTF-8 replaced), and index of the file's next block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Point {
    file: u64,
    line: u32,
    text: usize,
    block: usize,
}

/// Whole lines of the file, parsed.
#[derive(Debug)]
struct Piece {
    /// Where its first line starts.
    start: Point,
    /// Index in the file of `prog.blocks[0]`.
    first: usize,
    prog: Program,
    /// Where the next line starts.
    end: Point,
    /// Bytes read.
    bytes: usize,
}

impl Piece {
    fn holds(&self, n: usize) -> bool {
        self.first <= n && n < self.first + self.prog.blocks.len()
    }
}

/// The file and what the first reading learned of it.
struct Source<'r> {
    reader: Box<dyn ProgramRead + 'r>,
    /// The reader's offset.
    pos: u64,
    chunk_bytes: usize,
    block_delete: bool,
    buf: Vec<u8>,
    parser: ChunkParser,
    /// Where the first reading goes on.
    frontier: Point,
    /// The first reading has reached the end of the file.
    eof: bool,
    /// The first reading found a parse error: nothing runs any more.
    parse_failed: bool,
    analyser: Analyser,
    /// The start's diagnostics, then the analysis' (as in a whole-program run).
    flow_sink: Sink,
    /// Per O-word statement (block index): where its line starts.
    index: BTreeMap<usize, Point>,
    /// Where the piece in which the run ended starts.
    mark: Option<Point>,
    cache: VecDeque<Piece>,
    /// The file's last block.
    last_span: Option<Span>,
}

impl Source<'_> {
    /// Read whole lines from `at` until `limit` bytes (at least one line) into `buf`.
    fn read(&mut self, at: u64, limit: usize) -> Result<(), Error> {
        let read_err = |e: std::io::Error| Error::Read {
            message: e.to_string(),
        };
        if self.pos != at {
            self.reader.seek(SeekFrom::Start(at)).map_err(read_err)?;
            self.pos = at;
        }
        self.buf.clear();
        while self.buf.len() < limit.max(1) {
            let n = self
                .reader
                .read_until(b'\n', &mut self.buf)
                .map_err(read_err)?;
            if n == 0 {
                break;
            }
        }
        self.pos += self.buf.len() as u64;
        Ok(())
    }

    /// The first reading's next piece: parsed, its O-word statements analysed and indexed;
    /// `false` at the end of the file (the analysis is then complete).
    fn advance(&mut self, flow: &mut Flow) -> Result<bool, Error> {
        if self.eof {
            return Ok(false);
        }
        let start = self.frontier;
        self.read(start.file, self.chunk_bytes)?;
        if self.buf.is_empty() {
            self.eof = true;
            std::mem::take(&mut self.analyser).finish(flow, &mut self.flow_sink);
            return Ok(false);
        }
        let text = String::from_utf8_lossy(&self.buf);
        let prog = self.parser.parse_piece(&text);
        let (line, base) = self.parser.position();
        let end = Point {
            file: start.file + self.buf.len() as u64,
            line,
            text: base,
            block: start.block + prog.blocks.len(),
        };
        self.frontier = end;
        if let Some(b) = prog.blocks.last() {
            self.last_span = Some(b.span);
        }
        self.parse_failed |= self.parser.has_errors();
        if self.parse_failed {
            return Ok(true);
        }
        // Byte offsets of the lines, needed only where the text is not the file's bytes.
        let mut lines: Option<Vec<usize>> = None;
        for (k, b) in prog.blocks.iter().enumerate() {
            if b.o_word.is_none() || (b.block_delete && self.block_delete) {
                continue;
            }
            let g = start.block + k;
            let offset = match &text {
                Cow::Borrowed(_) => b.span.start - start.text,
                Cow::Owned(_) => {
                    let lines = lines.get_or_insert_with(|| line_offsets(&self.buf));
                    lines[(b.line - start.line - 1) as usize]
                }
            };
            let at = Point {
                file: start.file + offset as u64,
                line: b.line - 1,
                text: b.span.start,
                block: g,
            };
            self.index.insert(g, at);
            self.analyser
                .statement(g, b, self.parser.names(), flow, &mut self.flow_sink);
        }
        drop(text);
        let bytes = self.buf.len();
        self.keep(Piece {
            start,
            first: start.block,
            prog,
            end,
            bytes,
        });
        Ok(true)
    }

    /// Read again, from `at`, lines the first reading has read.
    fn read_again(&mut self, at: Point, limit: usize) -> Result<bool, Error> {
        self.read(at.file, limit)?;
        if self.buf.is_empty() {
            return Ok(false);
        }
        let text = String::from_utf8_lossy(&self.buf);
        let (prog, line, base) = self.parser.parse_again(&text, at.line, at.text);
        drop(text);
        let bytes = self.buf.len();
        let end = Point {
            file: at.file + bytes as u64,
            line,
            text: base,
            block: at.block + prog.blocks.len(),
        };
        self.keep(Piece {
            start: at,
            first: at.block,
            prog,
            end,
            bytes,
        });
        Ok(true)
    }

    /// Cache a piece, dropping the least recently used ones beyond the budget.
    fn keep(&mut self, piece: Piece) {
        self.cache.push_back(piece);
        let budget = 3 * self.chunk_bytes;
        while self.cache.len() > CACHE_PIECES
            || (self.cache.len() > 2 && self.cache.iter().map(|p| p.bytes).sum::<usize>() > budget)
        {
            self.cache.pop_front();
        }
    }

    /// Put the piece holding block `n` at the back of the cache (reading it if needed); `false`
    /// past the file's last block (or after a parse error).
    fn locate(&mut self, n: usize, flow: &mut Flow) -> Result<bool, Error> {
        loop {
            if let Some(i) = self.cache.iter().position(|p| p.holds(n)) {
                if i + 1 != self.cache.len()
                    && let Some(p) = self.cache.remove(i)
                {
                    self.cache.push_back(p);
                }
                return Ok(true);
            }
            if n >= self.frontier.block {
                if !self.advance(flow)? || self.parse_failed {
                    return Ok(false);
                }
                continue;
            }
            // Behind the first reading: on from the nearest known line start before the block
            // (the end of a cached piece, an indexed statement, where the run ended, the
            // file's start); from a `sub` (a call), its body up to the endsub.
            let chunk = self.chunk_bytes;
            let sub = n.checked_sub(1).and_then(|s| match flow.jumps.get(&s) {
                Some(Jump::Sub { end }) => Some((self.index.get(&s)?, self.index.get(end)?)),
                _ => None,
            });
            let known = self.index.range(..=n).next_back().map(|(_, p)| *p);
            let ends = self.cache.iter().map(|p| p.end);
            let at = ends
                .chain(known)
                .chain(self.mark)
                .filter(|p| p.block <= n)
                .max_by_key(|p| (p.block, p.file))
                .unwrap_or(Point {
                    file: 0,
                    line: 0,
                    text: 0,
                    block: 0,
                });
            let limit = match sub {
                Some((s, e)) if *s == at => chunk.min((e.file - s.file) as usize + 1),
                _ => chunk,
            };
            if !self.read_again(at, limit)? {
                return Err(Error::Read {
                    message: "the program got shorter while it was read".into(),
                });
            }
        }
    }
}

/// Byte offset in `buf` of the start of each line.
fn line_offsets(buf: &[u8]) -> Vec<usize> {
    std::iter::once(0)
        .chain(
            buf.iter()
                .enumerate()
                .filter(|(_, b)| **b == b'\n')
                .map(|(i, _)| i + 1),
        )
        .collect()
}

/// Where the run is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Run(Next),
    /// Ended at block `at` (by `M2`/`M30`/`%` on line `line`, or by an error or the file's end).
    Ended {
        at: usize,
        line: Option<u32>,
    },
    /// Too many moves.
    Stopped,
    /// A parse, start or control-flow error: nothing runs.
    Halted,
}

/// An interpreter that reads its program from a [`ProgramRead`] a piece at a time (docs/performance.md,
/// "Streaming"), handing back the moves as they are made. For any program, the moves, the
/// toolpath's start and axes and the diagnostics are those of [`crate::load`]'s parse and
/// [`super::interpret`] on the whole program (tested in `tests/streaming.rs`), in memory that
/// does not grow with the program's length.
pub struct ChunkInterp<'r> {
    opts: InterpOptions,
    source: Source<'r>,
    flow: Flow,
    carry: Option<Carry>,
    phase: Phase,
}

impl<'r> ChunkInterp<'r> {
    /// An interpreter at the start of the program `reader` (at its offset 0), reading about
    /// `chunk_bytes` at a time.
    pub fn new(
        reader: Box<dyn ProgramRead + 'r>,
        opts: &InterpOptions,
        chunk_bytes: usize,
    ) -> Self {
        let parse_opts = ParseOptions {
            lenient: opts.lenient,
            // Pieces bound the memory; the block count does not matter here.
            max_blocks: usize::MAX,
            ..ParseOptions::default()
        };
        let empty = Program::default();
        let it = Interp::new(&empty, opts);
        let flow_sink = it.sink.clone();
        let carry = it.into_carry();
        let phase = if carry.sink.has_errors() {
            Phase::Halted
        } else {
            Phase::Run(Next::Goto(0))
        };
        let start = Point {
            file: 0,
            line: 0,
            text: 0,
            block: 0,
        };
        ChunkInterp {
            opts: opts.clone(),
            source: Source {
                reader,
                pos: u64::MAX,
                chunk_bytes: chunk_bytes.max(1),
                block_delete: opts.block_delete,
                buf: Vec::new(),
                parser: ChunkParser::new(&parse_opts),
                frontier: start,
                eof: false,
                parse_failed: false,
                analyser: Analyser::default(),
                flow_sink,
                index: BTreeMap::new(),
                mark: None,
                cache: VecDeque::new(),
                last_span: None,
            },
            flow: Flow::default(),
            carry: Some(carry),
            phase,
        }
    }

    /// `true` once an error has been found (parse, control flow or run).
    pub fn has_errors(&self) -> bool {
        self.source.parse_failed
            || self.source.flow_sink.has_errors()
            || self.carry.as_ref().is_some_and(|c| c.sink.has_errors())
    }

    /// Run on until moves are ready and append them to `out` (in order, after those handed
    /// before; the last move made is kept back, a following `M0`/`M2` may still mark it as a
    /// stop). `false` once nothing more runs.
    pub fn next_moves(&mut self, out: &mut Vec<Move>) -> Result<bool, Error> {
        loop {
            if self.source.parse_failed || self.source.flow_sink.has_errors() {
                self.phase = Phase::Halted;
            }
            let Phase::Run(next) = self.phase else {
                return Ok(false);
            };
            let n = match next {
                Next::Goto(n) | Next::Test(n) => n,
                Next::End => usize::MAX,
            };
            let found = self.source.locate(n, &mut self.flow)?;
            let Some(piece) = self.source.cache.back().filter(|_| found) else {
                // Past the last block: the program ends without an end.
                self.phase = Phase::Ended { at: n, line: None };
                continue;
            };
            let Some(carry) = self.carry.take() else {
                return Ok(false);
            };
            let piece_start = piece.start;
            let names = self.source.parser.names();
            let mut it = Interp::resume(&piece.prog, piece.first, names, &self.opts, carry);
            let exit = it.run_piece(next, &self.flow, YIELD_MOVES);
            // Under StartPosition::FirstMove the first motion still rewrites the moves before
            // it; the last move may still be marked as a stop.
            if it.st.started && it.tp.moves.len() > 1 {
                let keep = it.tp.moves.len() - 1;
                out.extend(it.tp.moves.drain(..keep));
            }
            self.carry = Some(it.into_carry());
            self.phase = match exit {
                Exit::Leave(n) | Exit::Yield(n) => Phase::Run(n),
                Exit::Unresolved(n) => {
                    self.source.advance(&mut self.flow)?;
                    Phase::Run(n)
                }
                Exit::End { at, line } => {
                    self.source.mark = Some(piece_start);
                    Phase::Ended { at, line }
                }
                Exit::Stop => Phase::Stopped,
            };
            if !out.is_empty() {
                return Ok(true);
            }
        }
    }

    /// The end: reads the rest of the file for its diagnostics and returns the remaining moves
    /// (the last one marked as a stop), the toolpath's start and used axes (in a [`Toolpath`]
    /// holding only the remaining moves) and every diagnostic, the parser's first; or
    /// [`Error::Program`] with every diagnostic when one is an error.
    pub fn finish(mut self) -> Result<(Toolpath, Vec<Diagnostic>), Error> {
        while self.source.advance(&mut self.flow)? {}
        let parser = std::mem::replace(
            &mut self.source.parser,
            ChunkParser::new(&ParseOptions::default()),
        );
        let mut diags = parser.finish();
        if self.source.parse_failed {
            return Err(Error::Program { diagnostics: diags });
        }
        if self.source.flow_sink.has_errors() {
            diags.extend(std::mem::replace(&mut self.source.flow_sink, Sink::new(1)).finish());
            return Err(Error::Program { diagnostics: diags });
        }
        let Some(mut carry) = self.carry.take() else {
            return Err(Error::Program { diagnostics: diags });
        };
        let src = &mut self.source;
        match self.phase {
            Phase::Ended {
                at,
                line: Some(end_line),
            } => {
                // The analysis is complete: reading on needs no table.
                let flow = std::mem::take(&mut self.flow);
                let mut none = Flow::default();
                let mut get = |i: usize| -> Result<Option<(bool, Span)>, Error> {
                    let found = src.locate(i, &mut none)?;
                    Ok(src.cache.back().filter(|_| found).and_then(|p| {
                        p.prog
                            .blocks
                            .get(i - p.first)
                            .map(|b| (has_code(b), b.span))
                    }))
                };
                if let Some(w) = after_end(&flow, at, end_line, &mut get)? {
                    carry.sink.push(w);
                }
            }
            Phase::Stopped => {}
            _ => {
                if let Some(span) = src.last_span {
                    carry.sink.push(no_end_warning(span));
                }
            }
        }
        super::comp::release_into(&mut carry.st.comp, &mut carry.tp);
        match conclude(carry.sink, carry.tp) {
            Ok((tp, d)) => {
                diags.extend(d);
                Ok((tp, diags))
            }
            Err(d) => {
                diags.extend(d);
                Err(Error::Program { diagnostics: diags })
            }
        }
    }
}
