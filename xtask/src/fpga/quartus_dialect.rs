//! The Quartus-dialect gate: SystemVerilog forms that Verilator and Yosys
//! accept but Quartus Prime Standard/Lite rejects (or maps badly), found at
//! the lexer level so no Quartus is needed. Each finding is printed as
//! `file:line: rule: text`; `cargo xtask rtl` fails on any.
//!
//! Rules and their public sources:
//!
//! * `generate-region`: a loop or conditional generate outside
//!   `generate ... endgenerate`. M. Pikula, "Intel Quartus SystemVerilog
//!   gotchas" 27.4 and 27.5; lowRISC/ibex#117 (19.1 Lite does not compile
//!   without explicit `generate ... endgenerate` and `genvar`);
//!   openhwgroup/cv32e40p#1050 (25.1std Lite: generate/endgenerate are not
//!   optional).
//! * `genvar-in-for`: `for (genvar i = ...)`; the genvar must be declared
//!   before the loop. Pikula 27.4; lowRISC/ibex#117; openhwgroup/cv32e40p#1050.
//! * `localparam-in-parameter-port-list`: `localparam` inside a module's
//!   `#( ... )`. pulp-platform/common_cells#29 ("Quartus has issues with
//!   localparams in ports") and its fix #49; ZipCPU/wb2axip#31.
//! * `unnamed-block-declares-variables`: a procedural `begin` without a label
//!   that declares variables, or a `for (int i ...)` loop with no named
//!   block around it. openhwgroup/cv32e40p#1050 ("requires named blocks"),
//!   openhwgroup/cv32e40p#1035 (Error 10644 "this block requires a name").
//! * `computed-width-cast`: a size cast whose width is an expression,
//!   `(expr)'(x)` or `$bits(x)'(y)`; a named width (`localparam int W`)
//!   is the form every tool parses (verilator/verilator#865 shows tools
//!   differing on cast sizes).
//! * `elaboration-task-outside-translate-off`: `$error`, `$fatal`,
//!   `$warning` or `$info` that synthesis would see; Quartus Standard fails
//!   on simulation-only system tasks (Error 10174 in
//!   jbush001/NyuziProcessor#192, litex-hub/litex-boards#538).
//! * `cast-widened-multiplication`: `NN'(x) * y` or `x * NN'(y)`: operands
//!   widened by a cast make a wider multiplier than the DSP block's natural
//!   mode (amaranth-lang/amaranth#1148: Quartus used 2 DSP elements for an
//!   18x18 product; SpinalHDL/SpinalHDL#1477).
//!
//! Text between `// synthesis translate_off` and `translate_on` is dropped
//! first: Quartus never reads it.

use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};

use crate::support::Result;

/// One rule broken at one place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finding {
    pub line: usize,
    pub rule: &'static str,
    pub text: String,
}

/// A finding with the file it is in, for printing.
struct Located<'a> {
    file: &'a str,
    finding: &'a Finding,
}

impl fmt::Display for Located<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}: {}", self.file, self.finding.line, self.finding.rule, self.finding.text)
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Kind {
    /// Identifiers, keywords, system names (`$bits`), based-literal tails.
    Word,
    /// Unsigned decimal digits (the size of a sized literal or cast).
    Number,
    /// Operators and punctuation; `::` and `**` are single tokens.
    Punct,
}

#[derive(Debug, Clone)]
struct Token {
    kind: Kind,
    text: String,
    line: usize,
}

impl Token {
    fn is(&self, text: &str) -> bool {
        self.text == text
    }
}

/// Comment text that switches synthesis off or on (`synthesis`,
/// `pragma`, `synopsys` or `altera` prefixes are all honoured by Quartus).
fn translate_switch(comment: &str) -> Option<bool> {
    let words: Vec<&str> = comment.split_whitespace().collect();
    let prefixed =
        |w: &str| words.windows(2).any(|p| matches!(p[0], "synthesis" | "pragma" | "synopsys" | "altera") && p[1] == w);
    if prefixed("translate_off") {
        Some(false)
    } else if prefixed("translate_on") {
        Some(true)
    } else {
        None
    }
}

/// Tokens as synthesis sees them: comments and strings removed, and
/// everything between translate_off and translate_on dropped.
fn tokenize(src: &str) -> Vec<Token> {
    let chars: Vec<char> = src.chars().collect();
    let mut tokens = Vec::new();
    let mut line = 1;
    let mut synthesis_on = true;
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c.is_whitespace() {
            i += 1;
        } else if c == '/' && next == Some('/') {
            let start = i;
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
            let comment: String = chars[start..i].iter().collect();
            if let Some(on) = translate_switch(&comment) {
                synthesis_on = on;
            }
        } else if c == '/' && next == Some('*') {
            let start = i;
            i += 2;
            while i < chars.len() && !(chars[i] == '*' && chars.get(i + 1) == Some(&'/')) {
                if chars[i] == '\n' {
                    line += 1;
                }
                i += 1;
            }
            i = (i + 2).min(chars.len());
            let comment: String = chars[start..i].iter().collect();
            if let Some(on) = translate_switch(&comment) {
                synthesis_on = on;
            }
        } else if c == '"' {
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                if chars[i] == '\\' {
                    i += 1;
                } else if chars[i] == '\n' {
                    line += 1;
                }
                i += 1;
            }
            i += 1;
        } else {
            let start = i;
            let kind = if c.is_ascii_alphabetic() || c == '_' || c == '$' {
                while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '_' || chars[i] == '$') {
                    i += 1;
                }
                Kind::Word
            } else if c.is_ascii_digit() {
                while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '_') {
                    i += 1;
                }
                Kind::Number
            } else {
                let pair = matches!((c, next), (':', Some(':')) | ('*', Some('*')));
                i += if pair { 2 } else { 1 };
                Kind::Punct
            };
            if synthesis_on {
                tokens.push(Token { kind, text: chars[start..i].iter().collect(), line });
            }
        }
    }
    tokens
}

/// Keywords that start a variable declaration inside a procedural block.
const DECLARATION_KEYWORDS: &[&str] = &[
    "logic",
    "bit",
    "byte",
    "shortint",
    "int",
    "longint",
    "integer",
    "reg",
    "real",
    "time",
    "var",
    "automatic",
    "static",
    "const",
    "typedef",
    "localparam",
    "parameter",
];

/// Keywords that start a statement: never the type of a declaration.
const STATEMENT_KEYWORDS: &[&str] = &[
    "unique", "unique0", "priority", "if", "else", "for", "while", "do", "forever", "repeat", "foreach", "case",
    "casez", "casex", "return", "begin", "end", "fork", "assign", "force", "release", "disable", "wait", "void",
    "break", "continue",
];

const PROCEDURE_KEYWORDS: &[&str] = &["always", "always_ff", "always_comb", "always_latch", "initial", "final"];

struct Checker<'t> {
    tokens: &'t [Token],
    findings: Vec<Finding>,
}

impl Checker<'_> {
    fn at(&self, i: usize) -> Option<&Token> {
        self.tokens.get(i)
    }

    fn is(&self, i: usize, text: &str) -> bool {
        self.at(i).is_some_and(|t| t.is(text))
    }

    fn report(&mut self, i: usize, rule: &'static str, text: impl Into<String>) {
        let line = self.at(i).or(self.tokens.last()).map_or(0, |t| t.line);
        self.findings.push(Finding { line, rule, text: text.into() });
    }

    /// Index after the bracket that closes the one at `i` (`(`, `[` or `{`).
    fn skip_group(&self, i: usize) -> usize {
        let mut depth = 0usize;
        let mut j = i;
        while let Some(t) = self.at(j) {
            match t.text.as_str() {
                "(" | "[" | "{" => depth += 1,
                ")" | "]" | "}" => {
                    depth = depth.saturating_sub(1);
                    if depth == 0 {
                        return j + 1;
                    }
                }
                _ => {}
            }
            j += 1;
        }
        j
    }

    /// Index after the `;` ending the simple statement or declaration at `i`.
    fn skip_to_semicolon(&self, mut i: usize) -> usize {
        while let Some(t) = self.at(i) {
            match t.text.as_str() {
                "(" | "[" | "{" => i = self.skip_group(i),
                ";" => return i + 1,
                // A missing `;` must not swallow the block's end.
                "end" | "endcase" | "endfunction" | "endtask" | "endmodule" => return i,
                _ => i += 1,
            }
        }
        i
    }

    /// A declaration starts here: a type keyword, or a user type followed
    /// by the variable's name (`in_t r;`, `pkg::t r;`).
    fn is_declaration(&self, i: usize) -> bool {
        let Some(t) = self.at(i) else { return false };
        if DECLARATION_KEYWORDS.contains(&t.text.as_str()) {
            return true;
        }
        if STATEMENT_KEYWORDS.contains(&t.text.as_str()) {
            return false;
        }
        let word = |j: usize| self.at(j).is_some_and(|t| t.kind == Kind::Word && !t.text.starts_with('$'));
        if !word(i) {
            return false;
        }
        if self.is(i + 1, "::") {
            return word(i + 2) && word(i + 3);
        }
        word(i + 1)
    }

    /// One procedural statement at `i`; `named` tells whether a named
    /// scope (labelled block, function, task) encloses it. Returns the
    /// index after it.
    fn statement(&mut self, i: usize, named: bool) -> usize {
        let Some(t) = self.at(i) else { return i };
        match t.text.as_str() {
            "begin" | "fork" => self.block(i, named),
            "unique" | "unique0" | "priority" => self.statement(i + 1, named),
            "if" => {
                let mut j = self.statement(self.skip_group(i + 1), named);
                if self.is(j, "else") {
                    j = self.statement(j + 1, named);
                }
                j
            }
            "for" => {
                if !named && self.at(i + 2).is_some_and(|t| DECLARATION_KEYWORDS.contains(&t.text.as_str())) {
                    self.report(
                        i,
                        "unnamed-block-declares-variables",
                        "loop variable declared with no named block around it: label the enclosing block (`begin : p_name`)",
                    );
                }
                self.statement(self.skip_group(i + 1), named)
            }
            "while" | "repeat" | "foreach" => self.statement(self.skip_group(i + 1), named),
            "forever" => self.statement(i + 1, named),
            "do" => {
                let j = self.statement(i + 1, named);
                self.skip_to_semicolon(j)
            }
            "case" | "casez" | "casex" => self.case_items(self.skip_group(i + 1), named),
            "@" | "#" => {
                let j = if self.is(i + 1, "(") { self.skip_group(i + 1) } else { i + 2 };
                self.statement(j, named)
            }
            ";" => i + 1,
            _ => self.skip_to_semicolon(i),
        }
    }

    /// The items of a case statement from `i` to past its `endcase`.
    fn case_items(&mut self, mut i: usize, named: bool) -> usize {
        while let Some(t) = self.at(i) {
            if t.is("endcase") {
                return i + 1;
            }
            // Skip the item's labels up to its `:` (outside brackets).
            while let Some(t) = self.at(i) {
                match t.text.as_str() {
                    "(" | "[" | "{" => i = self.skip_group(i),
                    ":" => {
                        i += 1;
                        break;
                    }
                    "default" if !self.is(i + 1, ":") => {
                        i += 1;
                        break;
                    }
                    "endcase" => return i + 1,
                    _ => i += 1,
                }
            }
            i = self.statement(i, named);
        }
        i
    }

    /// A `begin ... end` block at `i`, with its optional label.
    fn block(&mut self, i: usize, named: bool) -> usize {
        let label = self.is(i + 1, ":");
        let mut j = if label { i + 3 } else { i + 1 };
        let mut reported = false;
        while let Some(t) = self.at(j) {
            if t.is("end") || t.is("join") || t.is("join_any") || t.is("join_none") {
                j += 1;
                if self.is(j, ":") {
                    j += 2;
                }
                return j;
            }
            if self.is_declaration(j) {
                if !label && !reported {
                    self.report(
                        j,
                        "unnamed-block-declares-variables",
                        "variables declared in an unnamed block: label it (`begin : p_name`)",
                    );
                    reported = true;
                }
                j = self.skip_to_semicolon(j);
            } else {
                let next = self.statement(j, named || label);
                j = if next > j { next } else { j + 1 };
            }
        }
        j
    }

    /// A function or task at `i` up to past its end keyword: a named scope.
    fn subroutine(&mut self, i: usize, end: &str) -> usize {
        let mut j = self.skip_to_semicolon(i + 1);
        while let Some(t) = self.at(j) {
            if t.is(end) {
                j += 1;
                if self.is(j, ":") {
                    j += 2;
                }
                return j;
            }
            if self.is_declaration(j) || t.is("input") || t.is("output") || t.is("inout") {
                j = self.skip_to_semicolon(j);
            } else {
                let next = self.statement(j, true);
                j = if next > j { next } else { j + 1 };
            }
        }
        j
    }

    /// The `#( ... )` parameter port list at `i`: no localparam inside.
    fn parameter_port_list(&mut self, i: usize) -> usize {
        let end = self.skip_group(i);
        for j in i..end {
            if self.is(j, "localparam") {
                self.report(
                    j,
                    "localparam-in-parameter-port-list",
                    "move it into the module body (compute a port width from parameters in the port declaration)",
                );
            }
        }
        end
    }

    /// Module items and package items: generate regions, procedures,
    /// subroutines, parameter port lists.
    fn items(&mut self) {
        let mut generate_depth = 0usize;
        // begin/end of generate blocks that lie outside a generate region
        // (already reported once, at their `if`/`for`/`case`).
        let mut bare_block_depth = 0usize;
        let mut i = 0;
        while let Some(t) = self.at(i) {
            match t.text.as_str() {
                "generate" => generate_depth += 1,
                "endgenerate" => generate_depth = generate_depth.saturating_sub(1),
                "module" | "interface" | "program" => {
                    // module NAME [import ...;]* #( ... )
                    let mut j = i + 2;
                    while self.is(j, "import") {
                        j = self.skip_to_semicolon(j);
                    }
                    if self.is(j, "#") && self.is(j + 1, "(") {
                        i = self.parameter_port_list(j + 1);
                        continue;
                    }
                }
                "function" => {
                    i = self.subroutine(i, "endfunction");
                    continue;
                }
                "task" => {
                    i = self.subroutine(i, "endtask");
                    continue;
                }
                kw if PROCEDURE_KEYWORDS.contains(&kw) => {
                    i = self.statement(i + 1, false);
                    continue;
                }
                "begin" if generate_depth == 0 && bare_block_depth > 0 => bare_block_depth += 1,
                "else" if generate_depth == 0 && self.is(i + 1, "begin") => {
                    bare_block_depth += 1;
                    i += 2;
                    continue;
                }
                "end" if generate_depth == 0 && bare_block_depth > 0 => bare_block_depth -= 1,
                "for" | "if" | "case" if generate_depth == 0 => {
                    let continues_construct = i > 0 && self.is(i - 1, "else");
                    if bare_block_depth == 0 && !continues_construct {
                        self.report(
                            i,
                            "generate-region",
                            format!("`{}` generate outside `generate ... endgenerate`", t.text),
                        );
                    }
                    // Its blocks count as one construct: no nested reports.
                    let after_header = self.skip_group(i + 1);
                    if self.is(after_header, "begin") {
                        bare_block_depth += 1;
                        i = after_header + 1;
                        continue;
                    }
                }
                _ => {}
            }
            i += 1;
        }
    }

    /// Rules that look at a few tokens anywhere.
    fn local_forms(&mut self) {
        for i in 0..self.tokens.len() {
            if self.is(i, "for") && self.is(i + 1, "(") && self.is(i + 2, "genvar") {
                self.report(i, "genvar-in-for", "declare the genvar before the loop (`genvar i;`)");
            }
            if self.is(i, ")") && self.is(i + 1, "'") && self.is(i + 2, "(") {
                self.report(
                    i,
                    "computed-width-cast",
                    "cast width is an expression: name it (`localparam int W = ...; W'(x)`)",
                );
            }
            if let Some(t) = self.at(i) {
                if matches!(t.text.as_str(), "$error" | "$fatal" | "$warning" | "$info") {
                    let text = format!("`{}` outside `// synthesis translate_off`", t.text);
                    self.report(i, "elaboration-task-outside-translate-off", text);
                }
            }
            let sized_cast = |j: usize| {
                self.at(j).is_some_and(|t| t.kind == Kind::Number) && self.is(j + 1, "'") && self.is(j + 2, "(")
            };
            if sized_cast(i) {
                let widened_left = self.is(self.skip_group(i + 2), "*");
                let widened_right = i > 0 && self.is(i - 1, "*");
                if widened_left || widened_right {
                    self.report(
                        i,
                        "cast-widened-multiplication",
                        "operand widened by a cast: multiply at the operands' width into a wide enough target",
                    );
                }
            }
        }
    }
}

/// All findings in one SystemVerilog source, in line order.
pub fn check_source(src: &str) -> Vec<Finding> {
    let tokens = tokenize(src);
    let mut checker = Checker { tokens: &tokens, findings: Vec::new() };
    checker.items();
    checker.local_forms();
    checker.findings.sort_by_key(|f| f.line);
    checker.findings
}

/// The `.sv` files directly in `dirs`, sorted.
fn sv_files(dirs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for dir in dirs {
        let entries = fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        for entry in entries {
            let path = entry.map_err(|e| format!("{}: {e}", dir.display()))?.path();
            if path.extension().is_some_and(|x| x == "sv") {
                files.push(path);
            }
        }
    }
    files.sort();
    Ok(files)
}

/// `cargo xtask rtl`'s first step: fpga/rtl and fpga/quartus.
pub fn run(root: &Path) -> Result<()> {
    let files = sv_files(&[root.join("fpga/rtl"), root.join("fpga/quartus")])?;
    let mut total = 0;
    for path in &files {
        let src = fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let shown = path.strip_prefix(root).unwrap_or(path).display().to_string();
        for finding in check_source(&src) {
            println!("{}", Located { file: &shown, finding: &finding });
            total += 1;
        }
    }
    println!("==> Quartus dialect gate: {} files, {total} findings", files.len());
    if total > 0 {
        return Err(format!("Quartus dialect gate: {total} findings (listed above)"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_repositorys_sources_pass_the_gate() {
        run(&crate::support::tools::root()).expect("fpga/rtl and fpga/quartus in Quartus 18.1's dialect");
    }

    fn rules(src: &str) -> Vec<&'static str> {
        check_source(src).into_iter().map(|f| f.rule).collect()
    }

    #[test]
    fn loop_generate_needs_a_generate_region_and_an_outer_genvar() {
        let bad =
            "module m;\n  for (genvar i = 0; i < 4; i++) begin : g_x\n    assign a[i] = b[i];\n  end\nendmodule\n";
        assert_eq!(rules(bad), ["generate-region", "genvar-in-for"]);
        assert_eq!(check_source(bad)[0].line, 2);
        let good = "module m;\n  generate\n    genvar i;\n    for (i = 0; i < 4; i = i + 1) begin : g_x\n      \
                    assign a[i] = b[i];\n    end\n  endgenerate\nendmodule\n";
        assert!(rules(good).is_empty());
    }

    #[test]
    fn conditional_generate_needs_a_generate_region_once_per_construct() {
        let bad = "module m;\n  if (N == 0) begin : g_a\n    if (M) begin : g_b\n    end\n  end else if (N == 1) \
                   begin : g_c\n  end else begin : g_d\n  end\n  assign x = y;\nendmodule\n";
        assert_eq!(rules(bad), ["generate-region"]);
        let good = "module m;\n  generate\n    if (N == 0) begin : g_a\n    end else begin : g_d\n    end\n  \
                    endgenerate\nendmodule\n";
        assert!(rules(good).is_empty());
    }

    #[test]
    fn procedural_if_for_and_case_are_not_generates() {
        let src = "module m;\n  always_ff @(posedge c) if (e) q <= d;\n  always_comb begin : p_x\n    \
                   for (int i = 0; i < 2; i++) if (a[i]) k = i;\n    case (s) 1: y = 0; default: y = 1; endcase\n  \
                   end\nendmodule\n";
        assert!(rules(src).is_empty(), "{:?}", check_source(src));
    }

    #[test]
    fn localparam_in_parameter_port_list() {
        let bad = "module m\n  import p::*;\n#(\n  parameter int N = 4,\n  localparam int W = $clog2(N)\n) (\n  \
                   input logic [W-1:0] a_i\n);\nendmodule\n";
        let found = check_source(bad);
        assert_eq!(found.len(), 1);
        assert_eq!((found[0].rule, found[0].line), ("localparam-in-parameter-port-list", 5));
        let good = "module m #(\n  parameter int N = 4\n) (\n  input logic [$clog2(N)-1:0] a_i\n);\n  \
                    localparam int W = $clog2(N);\nendmodule\n";
        assert!(rules(good).is_empty());
    }

    #[test]
    fn unnamed_procedural_blocks_may_not_declare_variables() {
        let bad = "module m;\n  always_comb begin\n    int k;\n    k = 0;\n  end\nendmodule\n";
        assert_eq!(rules(bad), ["unnamed-block-declares-variables"]);
        let user_type = "module m;\n  always_comb begin\n    in_t r;\n    r = 0;\n  end\nendmodule\n";
        assert_eq!(rules(user_type), ["unnamed-block-declares-variables"]);
        let loop_var = "module m;\n  always_comb begin\n    n = 0;\n    for (int l = 0; l < 4; l++) n += a[l];\n  \
                        end\nendmodule\n";
        assert_eq!(rules(loop_var), ["unnamed-block-declares-variables"]);
        let good = "module m;\n  always_comb begin : p_count\n    int k;\n    k = 0;\n    \
                    for (int l = 0; l < 4; l++) begin\n      k += a[l];\n    end\n  end\n  \
                    function automatic int f(input int a);\n    int r;\n    for (int i = 0; i < a; i++) r += i;\n    \
                    return r;\n  endfunction\nendmodule\n";
        assert!(rules(good).is_empty(), "{:?}", check_source(good));
    }

    #[test]
    fn cast_widths_must_be_named() {
        let bad = "module m;\n  assign n = n_q + ($clog2(D)+1)'(push) - $bits(n_q)'(pop);\nendmodule\n";
        assert_eq!(rules(bad), ["computed-width-cast", "computed-width-cast"]);
        let good = "module m;\n  localparam int CntW = $clog2(D) + 1;\n  assign n = n_q + CntW'(push) - 4'(pop) \
                    + q_t'(x) + '0 + 4'b0;\nendmodule\n";
        assert!(rules(good).is_empty());
    }

    #[test]
    fn elaboration_tasks_only_inside_translate_off() {
        let bad = "module m;\n  generate\n    if (N != 2) begin : g_check\n      $error(\"N\");\n    end\n  \
                   endgenerate\nendmodule\n";
        let found = check_source(bad);
        assert_eq!(found.len(), 1);
        assert_eq!((found[0].rule, found[0].line), ("elaboration-task-outside-translate-off", 4));
        let good = "module m;\n  // synthesis translate_off\n  if (N != 2) begin : g_check\n    \
                    $fatal(1, \"N\");\n  end\n  // synthesis translate_on\nendmodule\n";
        assert!(rules(good).is_empty());
        // Comments and strings never count.
        assert!(rules("module m;\n  // $error(\"x\") for (genvar i\n  /* 48'(a) * b */\nendmodule\n").is_empty());
    }

    #[test]
    fn multiplications_take_operands_at_their_width() {
        let bad = "module m;\n  always_ff @(posedge c) begin\n    p <= 48'(a) * 48'(b);\n    \
                   s <= $signed(30'(w) * 30'(w));\n    r <= x * 37'(y);\n  end\nendmodule\n";
        assert_eq!(rules(bad), ["cast-widened-multiplication"; 5]);
        let good = "module m;\n  always_ff @(posedge c) begin\n    p <= a * b;\n    q <= w * $signed({1'b0, r});\n    \
                    y <= qround(64'(p) + 64'(q));\n  end\nendmodule\n";
        assert!(rules(good).is_empty());
    }
}
