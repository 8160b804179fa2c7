// Verilator co-simulation of rt_top against golden rows from the Rust model.
//
// The bus sequence per row is hal-avalon's driver (src/driver.rs run_row):
// write ROW_Y and LIGHT_X/Y/Z, write CONTROL clear_done, write CONTROL start,
// poll STATUS until done, read the 480 line-buffer words. Every pixel is
// compared with the golden file (`cargo xtask golden` format: a `//` header
// `// golden rows A..B light raw X Y Z`, then one 8-digit hex word per pixel).
//
// Usage: tb_rt_top [--frame FILE]... [--extra FILE] [--max-errors N]
//   --frame: a whole-frame golden file (rows 0..360): rendered and compared.
//   --extra: golden rows 360..512 of some light: register-semantics checks
//            (start while busy, clear_done, ROW_Y >= 360, readback widths).
// Exit status 0 only if every check passed.
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "Vrt_top.h"
#include "verilated.h"

namespace {

constexpr uint32_t kControl = 0x00, kStatus = 0x04, kRowY = 0x08;
constexpr uint32_t kLightX = 0x0C, kLightY = 0x10, kLightZ = 0x14, kId = 0x18;
constexpr uint32_t kLine = 0x1000;
constexpr uint32_t kStart = 1, kClearDone = 2;
constexpr uint32_t kBusy = 1, kDone = 2;
constexpr int kWidth = 480, kHeight = 360;

struct Golden {
  std::string path;
  int first_row = 0, rows = 0;
  int32_t light[3] = {0, 0, 0};
  std::vector<uint32_t> words;
  const uint32_t *row(int y) const { return &words[size_t(y - first_row) * kWidth]; }
  bool has_row(int y) const { return y >= first_row && y < first_row + rows; }
};

bool load_golden(const std::string &path, Golden &g) {
  std::ifstream in(path);
  if (!in) {
    fprintf(stderr, "cannot open %s\n", path.c_str());
    return false;
  }
  std::string header;
  std::getline(in, header);
  int a = 0, b = 0;
  long x = 0, y = 0, z = 0;
  if (sscanf(header.c_str(), "// golden rows %d..%d light raw %ld %ld %ld", &a, &b, &x, &y, &z) != 5) {
    fprintf(stderr, "%s: unexpected header: %s\n", path.c_str(), header.c_str());
    return false;
  }
  g.path = path;
  g.first_row = a;
  g.rows = b - a;
  g.light[0] = int32_t(x);
  g.light[1] = int32_t(y);
  g.light[2] = int32_t(z);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    g.words.push_back(uint32_t(strtoul(line.c_str(), nullptr, 16)));
  }
  if (g.words.size() != size_t(g.rows) * kWidth) {
    fprintf(stderr, "%s: %zu words, expected %d\n", path.c_str(), g.words.size(), g.rows * kWidth);
    return false;
  }
  return true;
}

class Bench {
 public:
  Bench() : top_(new Vrt_top) {
    top_->clk_i = 0;
    top_->rst_ni = 0;
    top_->avs_read_i = 0;
    top_->avs_write_i = 0;
    top_->avs_address_i = 0;
    top_->avs_writedata_i = 0;
    top_->eval();
    tick();
    tick();
    top_->rst_ni = 1;
    tick();
  }
  ~Bench() { top_->final(); }

  // One clock: rising edge, then the falling edge where inputs change.
  void tick() {
    top_->clk_i = 1;
    top_->eval();
    top_->clk_i = 0;
    top_->eval();
    ++cycles_;
  }

  // One Avalon write transfer (no waitrequest).
  void write(uint32_t byte_off, uint32_t value) {
    top_->avs_address_i = byte_off >> 2;
    top_->avs_writedata_i = value;
    top_->avs_write_i = 1;
    tick();
    top_->avs_write_i = 0;
  }

  // One Avalon read transfer, fixed read latency 1.
  uint32_t read(uint32_t byte_off) {
    top_->avs_address_i = byte_off >> 2;
    top_->avs_read_i = 1;
    tick();
    top_->avs_read_i = 0;
    return top_->avs_readdata_o;
  }

  uint64_t cycles() const { return cycles_; }

 private:
  std::unique_ptr<Vrt_top> top_;
  uint64_t cycles_ = 0;
};

int g_errors = 0;
int g_max_errors = 20;

void fail(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
void fail(const char *fmt, ...) {
  ++g_errors;
  if (g_errors <= g_max_errors) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "MISMATCH: ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n");
    va_end(ap);
  }
}

void expect_eq(const char *what, uint32_t got, uint32_t want) {
  if (got != want) fail("%s: got 0x%08x, want 0x%08x", what, got, want);
}

uint32_t light_reg(int32_t raw) { return uint32_t(raw) & 0x00ffffffu; }

// Poll STATUS until done; returns cycles from the start write to done seen.
// Fails (and returns 0) if done never comes or STATUS has stray bits.
uint64_t poll_done(Bench &b, uint64_t start_cycle) {
  for (int i = 0; i < 1000000; ++i) {
    uint32_t s = b.read(kStatus);
    if (s & ~(kBusy | kDone)) {
      fail("STATUS reserved bits: 0x%08x", s);
      return 0;
    }
    if ((s & kBusy) && (s & kDone)) {
      fail("STATUS busy and done both set");
      return 0;
    }
    if (s & kDone) return b.cycles() - start_cycle;
  }
  fail("timeout waiting for done");
  return 0;
}

// The driver's row: registers, clear_done, start, poll, read 480 words.
uint64_t run_row(Bench &b, uint32_t row_reg, const int32_t light[3], uint32_t out[kWidth]) {
  b.write(kRowY, row_reg);
  b.write(kLightX, light_reg(light[0]));
  b.write(kLightY, light_reg(light[1]));
  b.write(kLightZ, light_reg(light[2]));
  b.write(kControl, kClearDone);
  b.write(kControl, kStart);
  uint64_t n = poll_done(b, b.cycles());
  for (int x = 0; x < kWidth; ++x) out[x] = b.read(kLine + 4 * x);
  return n;
}

int compare_row(const Golden &g, int y, const uint32_t got[kWidth], const char *ctx) {
  int bad = 0;
  const uint32_t *want = g.row(y);
  for (int x = 0; x < kWidth; ++x) {
    if (got[x] != want[x]) {
      ++bad;
      fail("%s %s row %d x %d: got %08x want %08x", ctx, g.path.c_str(), y, x, got[x], want[x]);
    }
  }
  return bad;
}

void check_frame(Bench &b, const Golden &g) {
  uint32_t row[kWidth];
  uint64_t frame = 0, row_min = ~0ull, row_max = 0;
  int bad = 0;
  for (int y = 0; y < kHeight; ++y) {
    uint64_t n = run_row(b, uint32_t(y), g.light, row);
    frame += n;
    row_min = n < row_min ? n : row_min;
    row_max = n > row_max ? n : row_max;
    bad += compare_row(g, y, row, "frame");
  }
  printf("frame light raw (%d, %d, %d): %d of %d pixels differ\n", g.light[0], g.light[1],
         g.light[2], bad, kWidth * kHeight);
  printf("cycles per row: %llu\n", (unsigned long long)row_max);
  if (row_min != row_max) printf("  (rows vary: min %llu)\n", (unsigned long long)row_min);
  printf("cycles per frame: %llu\n", (unsigned long long)frame);
  printf("frames/s at 50 MHz: %.1f\n", 50e6 / double(frame));
}

void check_registers(Bench &b, const Golden &extra, const Golden *frame) {
  // Out of reset: everything zero, ID fixed, unmapped offsets read 0.
  expect_eq("STATUS after reset", b.read(kStatus), 0);
  expect_eq("ROW_Y after reset", b.read(kRowY), 0);
  expect_eq("LIGHT_X after reset", b.read(kLightX), 0);
  expect_eq("LIGHT_Y after reset", b.read(kLightY), 0);
  expect_eq("LIGHT_Z after reset", b.read(kLightZ), 0);
  expect_eq("ID", b.read(kId), 0x52540001u);
  expect_eq("CONTROL reads 0", b.read(kControl), 0);
  expect_eq("unmapped 0x1c", b.read(0x1c), 0);
  expect_eq("unmapped 0xffc", b.read(0xffc), 0);
  expect_eq("line window past 480", b.read(kLine + 4 * 480), 0);
  expect_eq("line window end", b.read(0x1ffc), 0);

  // Widths and sign extension.
  b.write(kRowY, 0xffffffffu);
  expect_eq("ROW_Y keeps 9 bits", b.read(kRowY), 0x1ff);
  b.write(kLightX, 0x12345678u);
  expect_eq("LIGHT_X keeps 24 bits", b.read(kLightX), 0x00345678u);
  b.write(kLightY, 0x00800000u);
  expect_eq("LIGHT_Y sign-extends", b.read(kLightY), 0xff800000u);
  b.write(kLightZ, 0xfffffc00u);
  expect_eq("LIGHT_Z negative", b.read(kLightZ), 0xfffffc00u);
  b.write(kStatus, 0xffffffffu);
  expect_eq("STATUS ignores writes", b.read(kStatus), 0);
  b.write(kId, 0);
  expect_eq("ID ignores writes", b.read(kId), 0x52540001u);
  b.write(kControl, kClearDone);
  expect_eq("clear_done when idle", b.read(kStatus), 0);

  uint32_t row[kWidth];
  // ROW_Y >= 360 renders the extrapolated row, done set normally.
  for (int y : {360, 437, 511}) {
    if (!extra.has_row(y)) continue;
    run_row(b, uint32_t(y), extra.light, row);
    compare_row(extra, y, row, "ROW_Y>=360");
    expect_eq("STATUS after row", b.read(kStatus), kDone);
  }
  // Bits above 8 are dropped: 0xfffffe00 | 361 is row 361.
  if (extra.has_row(361)) {
    run_row(b, 0xfffffe00u | 361u, extra.light, row);
    compare_row(extra, 361, row, "ROW_Y masked");
  }

  // clear_done when done: done drops.
  expect_eq("done before clear", b.read(kStatus), kDone);
  b.write(kControl, kClearDone);
  expect_eq("clear_done clears done", b.read(kStatus), 0);

  // Start while busy is ignored; register writes while busy change readback
  // only; clear_done while busy leaves busy; start + clear_done: start wins.
  const int ya = 370, yb = 380;
  if (extra.has_row(ya) && extra.has_row(yb)) {
    b.write(kRowY, ya);
    b.write(kLightX, light_reg(extra.light[0]));
    b.write(kLightY, light_reg(extra.light[1]));
    b.write(kLightZ, light_reg(extra.light[2]));
    b.write(kControl, kStart | kClearDone);  // start wins
    uint64_t t0 = b.cycles();
    expect_eq("busy after start|clear_done", b.read(kStatus), kBusy);
    b.write(kRowY, yb);
    b.write(kLightX, 0x00001234u);
    expect_eq("ROW_Y readback while busy", b.read(kRowY), yb);
    expect_eq("LIGHT_X readback while busy", b.read(kLightX), 0x1234u);
    b.write(kControl, kStart);  // ignored
    b.write(kControl, kClearDone);
    expect_eq("clear_done while busy keeps busy", b.read(kStatus), kBusy);
    poll_done(b, t0);
    for (int x = 0; x < kWidth; ++x) row[x] = b.read(kLine + 4 * x);
    compare_row(extra, ya, row, "start-while-busy");
    expect_eq("done after ignored start", b.read(kStatus), kDone);
    // Done stays set and no second row runs.
    for (int i = 0; i < 2000; ++i) b.read(kStatus);
    expect_eq("no second row from ignored start", b.read(kStatus), kDone);
    // A start when done clears done and runs the row now in ROW_Y.
    b.write(kLightX, light_reg(extra.light[0]));
    b.write(kControl, kStart);
    expect_eq("start clears done", b.read(kStatus), kBusy);
    poll_done(b, b.cycles());
    for (int x = 0; x < kWidth; ++x) row[x] = b.read(kLine + 4 * x);
    compare_row(extra, yb, row, "restart");
  }

  // A row of a frame right after, with the frame's light.
  if (frame) {
    run_row(b, 180, frame->light, row);
    compare_row(*frame, 180, row, "after-register-checks");
  }
  printf("register checks done\n");
}

}  // namespace

int main(int argc, char **argv) {
  Verilated::commandArgs(argc, argv);
  std::vector<std::string> frames;
  std::string extra;
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--frame") && i + 1 < argc) frames.push_back(argv[++i]);
    else if (!strcmp(argv[i], "--extra") && i + 1 < argc) extra = argv[++i];
    else if (!strcmp(argv[i], "--max-errors") && i + 1 < argc) g_max_errors = atoi(argv[++i]);
    else if (argv[i][0] != '+') {
      fprintf(stderr, "usage: %s [--frame FILE]... [--extra FILE] [--max-errors N]\n", argv[0]);
      return 2;
    }
  }
  if (frames.empty() && extra.empty()) {
    fprintf(stderr, "nothing to check: give --frame and/or --extra\n");
    return 2;
  }
  std::vector<Golden> goldens(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    if (!load_golden(frames[i], goldens[i])) return 2;
    if (goldens[i].first_row != 0 || goldens[i].rows != kHeight) {
      fprintf(stderr, "%s: not a whole frame\n", frames[i].c_str());
      return 2;
    }
  }
  Bench bench;
  if (!extra.empty()) {
    Golden ex;
    if (!load_golden(extra, ex)) return 2;
    check_registers(bench, ex, goldens.empty() ? nullptr : &goldens[0]);
  }
  for (const Golden &g : goldens) check_frame(bench, g);
  if (g_errors) {
    printf("co-simulation FAILED: %d mismatches\n", g_errors);
    return 1;
  }
  printf("co-simulation passed: %zu frames, every pixel equal to the model\n", goldens.size());
  return 0;
}
