// Verilator co-simulation of rt_top against golden rows from the Rust model.
//
// Row mode: the bus sequence per row is hal-avalon's driver (src/driver.rs
// run_row): write ROW_Y and LIGHT_X/Y/Z, write CONTROL clear_done, write
// CONTROL start, poll STATUS until done, read the 480 line-buffer words.
// Frame mode: write FRAME_BASE and LIGHT_*, FRAME_CONTROL start, poll
// ROWS_DONE and FRAME_STATUS while an AXI3 memory model takes the frame
// DMA's bursts, under three slave behaviours (Platform Designer's master
// network interface, data before address, address long before data) with
// random wait states and random write-response delays; at every ROWS_DONE
// read the rows it reports must already have their write responses sent
// (the counter never runs ahead of the data), and at the end the bytes in
// memory must equal the golden frame as RGB888 wire bytes. An AXI3 protocol
// checker watches every clock; a frame with no write transfer for 300,000
// clocks fails as a deadlock. Then aborts, lost write responses and a port
// that answers nothing.
// Every pixel is compared with the golden file (`cargo xtask golden`
// format: a `//` header `// golden rows A..B light raw X Y Z`, then one
// 8-digit hex word per pixel).
//
// Usage: tb_rt_top [--frame FILE]... [--extra FILE] [--max-errors N] [--dma-only] [--mem-seed N]
//   --frame: a whole-frame golden file (rows 0..360): rendered and compared,
//            in row mode and in frame mode.
//   --extra: golden rows 360..512 of some light: register-semantics checks
//            (start while busy, clear_done, ROW_Y >= 360, readback widths).
//   --dma-only: frame mode only (skip the row-mode frames).
// Exit status 0 only if every check passed.
#include <algorithm>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <deque>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "Vrt_top.h"
#include "verilated.h"

namespace {

constexpr uint32_t kControl = 0x00, kStatus = 0x04, kRowY = 0x08;
constexpr uint32_t kLightX = 0x0C, kLightY = 0x10, kLightZ = 0x14, kId = 0x18;
constexpr uint32_t kFrameBase = 0x1C, kFrameControl = 0x20, kFrameStatus = 0x24, kRowsDone = 0x28;
constexpr uint32_t kLine = 0x1000;
constexpr uint32_t kStart = 1, kClearDone = 2, kAbort = 4;
constexpr uint32_t kBusy = 1, kDone = 2;
constexpr uint32_t kFrameBusy = 1, kFrameDone = 2, kFrameError = 4, kFrameAborted = 8;
constexpr uint32_t kVgaControl = 0x2C, kVgaBase = 0x30, kVgaStatus = 0x34, kKeys = 0x38, kSwitches = 0x3C;
constexpr uint32_t kLeds = 0x40, kHexLo = 0x44, kHexHi = 0x48;
constexpr uint32_t kVgaEnable = 1, kVgaLetterbox = 2, kVgaUnderrun = 1u << 16;
constexpr uint32_t kVgaReadError = 1u << 17, kVgaStall = 1u << 18;
// The VGA reader's bursts in flight: rt_accel_hw.tcl's readIssuingCapability.
constexpr int kReadIssuing = 4;
// hal-avalon VGA_STALL_CYCLES: the reader gives up on a port that answers
// nothing for this long.
constexpr uint64_t kVgaStallCycles = 1u << 17;
constexpr uint32_t kIdValue = 0x52540003u;
// BUILD_ID (0x4C): the co-simulation is verilated with -GBUILD_ID=<this>
// (xtask/src/fpga/rtl.rs, COSIM_BUILD_ID).
constexpr uint32_t kBuildIdOffset = 0x4c, kBuildId = 0x0123abcu;
constexpr uint32_t kKeyDebounce = 1u << 20;  // hal-avalon KEY_DEBOUNCE_CLOCKS
constexpr int kWidth = 480, kHeight = 360;
constexpr uint32_t kRowBytes = kWidth * 3, kFrameBytes = kRowBytes * kHeight;

// The memory behind the FPGA-to-SDRAM port.
constexpr uint32_t kMemBase = 0x01000000, kMemSize = 4u << 20;

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

void fail(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

// How the write slave behind the FPGA-to-SDRAM port takes AW and W. Every
// frame-mode run repeats under each, with random stalls and random
// write-response delays on top.
enum class Slave {
  // Platform Designer's AXI master network interface
  // (altera_merlin_axi_master_ni, between every fabric AXI master and the
  // f2h_sdram port): a W beat is taken only while AWVALID and WVALID are
  // both high, and AW is accepted together with the burst's WLAST beat. A
  // master that waits for AWREADY before raising WVALID deadlocks here.
  kPlatformDesigner,
  // W beats accepted before their AW: AWREADY only once a whole burst of
  // data has arrived ahead of it.
  kDataFirst,
  // AW accepted long before any W: W beats only 16 or more clocks after
  // their burst's AW handshake.
  kAddressFirst,
};

const char *slave_name(Slave s) {
  switch (s) {
    case Slave::kPlatformDesigner: return "Platform-Designer-like";
    case Slave::kDataFirst: return "data first";
    case Slave::kAddressFirst: return "address first";
  }
  return "?";
}

// The payloads of the write channels as the master drives them.
struct AwPayload {
  uint32_t addr;
  uint8_t len, size, burst, cache, prot;
  bool operator==(const AwPayload &o) const {
    return addr == o.addr && len == o.len && size == o.size && burst == o.burst && cache == o.cache && prot == o.prot;
  }
};
struct WPayload {
  uint64_t data;
  uint8_t strb;
  bool last;
  bool operator==(const WPayload &o) const { return data == o.data && strb == o.strb && last == o.last; }
};
struct ArPayload {
  uint32_t addr;
  uint8_t len, size, burst, cache, prot;
  bool operator==(const ArPayload &o) const {
    return addr == o.addr && len == o.len && size == o.size && burst == o.burst && cache == o.cache && prot == o.prot;
  }
};
template <class T> ArPayload ar_payload(T *top) {
  return ArPayload{top->axm_araddr_o,  uint8_t(top->axm_arlen_o),   uint8_t(top->axm_arsize_o),
                   uint8_t(top->axm_arburst_o), uint8_t(top->axm_arcache_o), uint8_t(top->axm_arprot_o)};
}
template <class T> AwPayload aw_payload(T *top) {
  return AwPayload{top->axm_awaddr_o,  uint8_t(top->axm_awlen_o),   uint8_t(top->axm_awsize_o),
                   uint8_t(top->axm_awburst_o), uint8_t(top->axm_awcache_o), uint8_t(top->axm_awprot_o)};
}
template <class T> WPayload w_payload(T *top) {
  return WPayload{top->axm_wdata_o, uint8_t(top->axm_wstrb_o), bool(top->axm_wlast_o)};
}

// AXI3 protocol checker for the master side of the write channels (ARM IHI
// 0022, AXI3 parts of issue E): every VALID stays high with a stable payload
// until its READY (A3.2.1); AWVALID and WVALID low in reset (A3.1.2);
// AWSIZE, AWBURST as the master promises (8-byte beats, INCR) and no burst
// across a 4 KiB boundary (A3.4.1); WLAST exactly on a burst's last beat and
// no more W beats than announced (A3.4.1, checked where the slave pairs W
// with AW); a write response accepted within a bounded time (BREADY).
class AxiChecker {
 public:
  // Only when the DMA gives up on a memory that answers nothing may a
  // VALID fall without its READY (a documented last resort).
  void allow_withdraw(bool on) { allow_withdraw_ = on; }
  uint64_t violations() const { return violations_; }
  int max_reads_in_flight() const { return max_reads_out_; }
  // A read slave that was reset forgets its bursts (the stall-limit test).
  void forget_reads() { reads_out_ = 0; }

  template <class T> void sample(T *top, bool awready, bool wready, bool bvalid, bool arready, bool rvalid) {
    if (!top->rst_ni) {
      if (seen_reset_ && (top->axm_awvalid_o || top->axm_wvalid_o || top->axm_arvalid_o))
        report("AWVALID/WVALID/ARVALID high in reset");
      seen_reset_ = true;
      aw_wait_ = w_wait_ = ar_wait_ = false;
      return;
    }
    // Read channels (the VGA reader): ARVALID held with a stable payload
    // until ARREADY (never withdrawn), 8-byte INCR beats, no burst across
    // 4 KiB, RREADY high whenever RVALID is (the reader promises it).
    ArPayload ar = ar_payload(top);
    if (ar_wait_) {
      if (!top->axm_arvalid_o) report("ARVALID fell before ARREADY");
      else if (!(ar == ar_)) report("AR payload changed while waiting for ARREADY");
    }
    if (top->axm_arvalid_o) {
      if (ar.size != 3) report("ARSIZE %u, promised 3 (8 bytes)", ar.size);
      if (ar.burst != 1) report("ARBURST %u, promised INCR", ar.burst);
      uint32_t end = ar.addr + 8u * (uint32_t(ar.len) + 1);
      if ((ar.addr >> 12) != ((end - 1) >> 12)) report("read burst 0x%08x+%u crosses 4 KiB", ar.addr, ar.len + 1u);
      if (ar.addr % 8) report("ARADDR 0x%08x not 8-byte aligned", ar.addr);
    }
    if (rvalid && !top->axm_rready_o) report("RREADY low while RVALID");
    // Bursts in flight, AR handshake to RLAST beat, within the declared
    // read issuing capability.
    if (top->axm_arvalid_o && arready) ++reads_out_;
    if (rvalid && top->axm_rready_o && top->axm_rlast_i) --reads_out_;
    if (reads_out_ > max_reads_out_) max_reads_out_ = reads_out_;
    if (reads_out_ > kReadIssuing) report("%d read bursts in flight, the declared capability is %d", reads_out_, kReadIssuing);
    ar_wait_ = top->axm_arvalid_o && !arready && !allow_withdraw_;
    ar_ = ar;
    AwPayload aw = aw_payload(top);
    WPayload w = w_payload(top);
    if (aw_wait_ && !allow_withdraw_) {
      if (!top->axm_awvalid_o) report("AWVALID fell before AWREADY");
      else if (!(aw == aw_)) report("AW payload changed while waiting for AWREADY");
    }
    if (w_wait_ && !allow_withdraw_) {
      if (!top->axm_wvalid_o) report("WVALID fell before WREADY");
      else if (!(w == w_))
        report("W payload changed while waiting for WREADY: data %016llx strb %02x last %d -> %016llx %02x %d",
               (unsigned long long)w_.data, w_.strb, w_.last, (unsigned long long)w.data, w.strb, w.last);
    }
    if (top->axm_awvalid_o) {
      if (aw.size != 3) report("AWSIZE %u, promised 3 (8 bytes)", aw.size);
      if (aw.burst != 1) report("AWBURST %u, promised INCR", aw.burst);
      uint32_t end = aw.addr + 8u * (uint32_t(aw.len) + 1);
      if ((aw.addr >> 12) != ((end - 1) >> 12)) report("burst 0x%08x+%u crosses 4 KiB", aw.addr, aw.len + 1u);
      if (aw.addr % 8) report("AWADDR 0x%08x not 8-byte aligned", aw.addr);
    }
    if (top->axm_wvalid_o && w.strb != 0xff && w.strb != 0x00) report("WSTRB 0x%02x: neither a full beat nor none", w.strb);
    aw_wait_ = top->axm_awvalid_o && !awready;
    w_wait_ = top->axm_wvalid_o && !wready;
    aw_ = aw;
    w_ = w;
    b_wait_ = (bvalid && !top->axm_bready_o) ? b_wait_ + 1 : 0;
    if (b_wait_ == 1000) report("BVALID waited 1,000 clocks for BREADY");
  }

 private:
  void report(const char *fmt, ...) __attribute__((format(printf, 2, 3))) {
    ++violations_;
    char buf[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fail("AXI protocol: %s", buf);
  }

  bool seen_reset_ = false, allow_withdraw_ = false;
  bool aw_wait_ = false, w_wait_ = false, ar_wait_ = false;
  ArPayload ar_{};
  AwPayload aw_{};
  WPayload w_{};
  uint64_t b_wait_ = 0, violations_ = 0;
  int reads_out_ = 0, max_reads_out_ = 0;
};

// An AXI3 write slave in front of a byte array: takes AW and W as its
// `Slave` behaviour says, with random stalls, pairs W beats with their
// bursts (in either order), and answers each burst after a random delay.
// It checks what only the slave can see (WLAST on the right beat, no W beat
// beyond those announced) and records, per frame row, when the last of its
// bytes got its write response.
class AxiMemory {
 public:
  explicit AxiMemory(uint32_t seed) : rng_(seed), mem_(kMemSize, 0) {}

  void set_behaviour(Slave s) { slave_ = s; }
  Slave behaviour() const { return slave_; }
  // Back-pressure: percent of cycles each ready is low, and the largest
  // write-response delay in cycles.
  void set_pressure(int aw_stall_pct, int w_stall_pct, int max_b_delay) {
    aw_stall_ = aw_stall_pct;
    w_stall_ = w_stall_pct;
    max_b_delay_ = max_b_delay;
  }
  // A write response SLVERR for any burst touching [addr, addr + len).
  void set_error_range(uint32_t addr, uint32_t len) { err_lo_ = addr, err_hi_ = addr + len; }
  // Write responses are lost: never sent (and forgotten when this ends).
  void set_lose_responses(bool on) {
    lose_ = on;
    if (!on) b_.clear();
  }
  // Nothing answers (a port held in reset); ending it resets the slave.
  void set_dead(bool on) {
    dead_ = on;
    if (!on) {
      aw_.clear();
      w_.clear();
      b_.clear();
    }
  }

  // Read channels: percent of cycles ARREADY is low, percent of cycles a
  // due R beat is held back (RVALID gaps), the largest AR-to-first-beat
  // latency.
  void set_read_pressure(int ar_stall_pct, int r_gap_pct, int max_latency) {
    ar_stall_ = ar_stall_pct;
    r_gap_ = r_gap_pct;
    max_r_latency_ = max_latency;
  }
  // The read channels answer nothing (a stall long enough to starve a
  // reader); bursts already accepted wait.
  void set_read_stall(bool on) { read_stall_ = on; }
  // The read port is held in reset: nothing answers, and when it comes
  // back it has forgotten every burst.
  void set_read_dead(bool on) {
    read_stall_ = on;
    if (!on) rq_.clear();
  }
  // Beats read from [addr, addr + len) answer SLVERR with garbage data.
  void set_read_error_range(uint32_t addr, uint32_t len) { rerr_lo_ = addr, rerr_hi_ = addr + len; }
  uint64_t read_bursts() const { return read_bursts_; }
  uint64_t read_beats() const { return read_beats_; }

  // A new frame at `base`: forget which rows landed.
  void begin_frame(uint32_t base) {
    frame_base_ = base;
    row_landed_bytes_.assign(kHeight, 0);
  }
  // Rows 0..n-1 of the frame whose every byte got its write response.
  int landed_rows() const {
    int n = 0;
    while (n < kHeight && row_landed_bytes_[n] == kRowBytes) ++n;
    return n;
  }
  uint8_t *bytes(uint32_t addr) { return &mem_[addr - kMemBase]; }
  const std::vector<uint8_t> &all() const { return mem_; }
  void fill(uint8_t v) { std::fill(mem_.begin(), mem_.end(), v); }
  // Bursts, W beats or responses the slave still holds.
  bool quiet() const { return aw_.empty() && w_.empty() && b_.empty(); }
  // Clock of the last handshake on any write channel.
  uint64_t last_transfer() const { return last_transfer_; }
  bool awready() const { return awready_; }
  bool wready() const { return wready_; }
  bool bvalid() const { return bvalid_; }

  // Inputs of the coming clock edge, from the master's outputs as they are
  // (AXI lets READY depend on VALID, never the other way round).
  template <class T> void drive(T *top, uint64_t now) {
    awready_ = wready_ = bvalid_ = false;
    if (!dead_) {
      switch (slave_) {
        case Slave::kPlatformDesigner:
          wready_ = top->axm_awvalid_o && top->axm_wvalid_o && roll(w_stall_);
          awready_ = wready_ && top->axm_wlast_o;
          break;
        case Slave::kDataFirst:
          wready_ = roll(w_stall_) && w_.size() < 64;
          awready_ = roll(aw_stall_) && bursts_of_data_ > aw_.size();
          break;
        case Slave::kAddressFirst:
          awready_ = roll(aw_stall_) && aw_.size() < 8;
          wready_ = roll(w_stall_) && !aw_.empty() && aw_.front().accepted + 16 <= now;
          break;
      }
      bvalid_ = !lose_ && !b_.empty() && b_.front().due <= now;
    }
    top->axm_awready_i = awready_;
    top->axm_wready_i = wready_;
    top->axm_bvalid_i = bvalid_;
    top->axm_bresp_i = bvalid_ ? b_.front().resp : 0;
    // Reads: bursts answered in order, beat by beat, from the memory; any
    // number accepted (the checker holds the master to its declared limit).
    arready_ = !read_stall_ && rroll(ar_stall_);
    rvalid_ = !read_stall_ && !rq_.empty() && rq_.front().due <= now && rroll(r_gap_);
    uint64_t data = 0;
    bool last = false, error = false;
    if (rvalid_) {
      const ReadBurst &r = rq_.front();
      uint32_t at = r.addr + 8u * uint32_t(r.done);
      error = at < rerr_hi_ && at + 8 > rerr_lo_;
      if (error) data = 0xdeadbeefdeadbeefull;
      else if (at >= kMemBase && at + 8 <= kMemBase + kMemSize)
        for (int i = 0; i < 8; ++i) data |= uint64_t(mem_[at - kMemBase + i]) << (8 * i);
      last = r.done + 1 == r.beats;
    }
    top->axm_arready_i = arready_;
    top->axm_rvalid_i = rvalid_;
    top->axm_rdata_i = rvalid_ ? data : 0x0123456789abcdefull;
    top->axm_rlast_i = rvalid_ && last;
    top->axm_rresp_i = error ? 2 : 0;  // SLVERR
  }
  bool arready() const { return arready_; }
  bool rvalid() const { return rvalid_; }

  // The handshakes of the clock edge, with the outputs as they were.
  template <class T> void edge(T *top, uint64_t now) {
    if (!top->rst_ni) return;  // registers are random until the reset edge
    if (top->axm_awvalid_o && awready_) {
      aw_.push_back(Burst{top->axm_awaddr_o, int(top->axm_awlen_o) + 1, 0, 0, false, now});
      Burst &b = aw_.back();
      uint32_t end = b.addr + 8u * b.beats;
      if (b.addr < kMemBase || end > kMemBase + kMemSize) fail("burst 0x%08x outside memory", b.addr);
      b.error = b.addr < err_hi_ && end > err_lo_;
      last_transfer_ = now;
    }
    if (top->axm_wvalid_o && wready_) {
      w_.push_back(w_payload(top));
      if (top->axm_wlast_o) ++bursts_of_data_;
      last_transfer_ = now;
    }
    pair(now);
    if (top->axm_arvalid_o && arready_) {
      ReadBurst r{top->axm_araddr_o, int(top->axm_arlen_o) + 1, 0, 0};
      uint64_t lat = max_r_latency_ ? rrng_() % (max_r_latency_ + 1) : 0;
      r.due = now + 1 + lat;
      if (r.addr < kMemBase || r.addr + 8u * r.beats > kMemBase + kMemSize) fail("read burst 0x%08x outside memory", r.addr);
      rq_.push_back(r);
      ++read_bursts_;
    }
    if (rvalid_ && top->axm_rready_o) {
      ReadBurst &r = rq_.front();
      ++read_beats_;
      if (++r.done == r.beats) rq_.pop_front();
    }
    if (bvalid_ && top->axm_bready_o) {
      const Resp &r = b_.front();
      for (int i = 0; i < r.beats; ++i)
        if (r.strobed >> i & 1) land(r.addr + 8u * i, 8);
      b_.pop_front();
      last_transfer_ = now;
    }
  }

 private:
  struct Burst {
    uint32_t addr;
    int beats, done;
    uint32_t strobed;  // beats written with their strobes on
    bool error;
    uint64_t accepted;
  };
  struct ReadBurst {
    uint32_t addr;
    int beats, done;
    uint64_t due;
  };
  struct Resp {
    uint64_t due;
    uint32_t addr;
    int beats;
    uint32_t strobed;
    uint8_t resp;
  };

  bool roll(int stall_pct) { return int(rng_() % 100) >= stall_pct; }
  // The read channels draw from their own generator, so the write
  // channels' random sequences do not depend on the reads.
  bool rroll(int stall_pct) { return int(rrng_() % 100) >= stall_pct; }

  // W beats meet their bursts in order, whichever came first.
  void pair(uint64_t now) {
    while (!aw_.empty() && !w_.empty()) {
      Burst &b = aw_.front();
      WPayload w = w_.front();
      w_.pop_front();
      uint32_t at = b.addr + 8u * b.done;
      if (!b.error && w.strb && at >= kMemBase && at + 8 <= kMemBase + kMemSize) {
        for (int i = 0; i < 8; ++i)
          if (w.strb >> i & 1) mem_[at - kMemBase + i] = uint8_t(w.data >> (8 * i));
      }
      if (w.strb == 0xff) b.strobed |= 1u << b.done;
      ++b.done;
      bool last = b.done == b.beats;
      if (w.last != last) fail("AXI protocol: WLAST %d on beat %d of a %d-beat burst", w.last, b.done, b.beats);
      if (last || w.last) {
        uint64_t delay = max_b_delay_ ? rng_() % (max_b_delay_ + 1) : 0;
        b_.push_back(Resp{now + 1 + delay, b.addr, b.done, b.strobed, uint8_t(b.error ? 2 : 0)});
        aw_.pop_front();
        --bursts_of_data_;
      }
    }
  }

  void land(uint32_t addr, uint32_t bytes) {
    for (uint32_t a = addr; a < addr + bytes; ++a) {
      if (a < frame_base_ || a >= frame_base_ + kFrameBytes) {
        fail("write response for 0x%08x, outside the frame", a);
        return;
      }
      ++row_landed_bytes_[(a - frame_base_) / kRowBytes];
    }
  }

  std::mt19937 rng_;
  std::vector<uint8_t> mem_;
  std::deque<Burst> aw_;
  std::deque<WPayload> w_;
  std::deque<Resp> b_;
  size_t bursts_of_data_ = 0;  // WLAST beats received, not yet paired
  std::vector<uint32_t> row_landed_bytes_ = std::vector<uint32_t>(kHeight, 0);
  uint32_t frame_base_ = kMemBase;
  uint32_t err_lo_ = 0, err_hi_ = 0;
  Slave slave_ = Slave::kPlatformDesigner;
  int aw_stall_ = 0, w_stall_ = 0, max_b_delay_ = 0;
  bool lose_ = false, dead_ = false;
  bool awready_ = true, wready_ = true, bvalid_ = false;
  uint64_t last_transfer_ = 0;
  std::deque<ReadBurst> rq_;
  std::mt19937 rrng_{777};
  int ar_stall_ = 0, r_gap_ = 0, max_r_latency_ = 0;
  uint32_t rerr_lo_ = 0, rerr_hi_ = 0;
  bool read_stall_ = false, arready_ = false, rvalid_ = false;
  uint64_t read_bursts_ = 0, read_beats_ = 0;
};


// ---- VGA monitor -------------------------------------------------------------

// 640x480@60 timing, one axis each (model::display H_TIMING and V_TIMING,
// given by xtask with --vga-timing): visible, front porch, sync, back porch.
struct Axis {
  int visible, front, sync, back;
  int total() const { return visible + front + sync + back; }
};
Axis g_h = {640, 16, 96, 48}, g_v = {480, 10, 2, 33};
// model::display::display_picture of an index frame (frame pixel i holds
// i + 1 as R<<16 | G<<8 | B), one per layout: 0 = black, else the frame
// pixel shown is the value less one. Written by xtask (--vga-map).
std::vector<uint8_t> g_map[2];
constexpr int kDispW = 640, kDispH = 480;

struct VgaPins {
  bool clk, hs, vs, blank_n, sync_n;
  uint8_t r, g, b;
  bool operator==(const VgaPins &o) const {
    return hs == o.hs && vs == o.vs && blank_n == o.blank_n && sync_n == o.sync_n && r == o.r && g == o.g && b == o.b;
  }
};
template <class T> VgaPins vga_pins(T *top) {
  return VgaPins{bool(top->vga_clk_o), bool(top->vga_hs_o), bool(top->vga_vs_o), bool(top->vga_blank_n_o),
                 bool(top->vga_sync_n_o), uint8_t(top->vga_r_o), uint8_t(top->vga_g_o), uint8_t(top->vga_b_o)};
}

// Samples the VGA outputs at every rising edge of vga_clk_o, as the DAC
// does: every output must be stable across that edge; after the first
// vertical sync every sample is checked against the timing exactly (sync
// widths, porches, totals, polarity, blank_n, black outside the visible
// area); each 640x480 picture is rebuilt and compared byte for byte with
// the model's mapping of the frame in memory at the base and layout the
// registers held at the start of the frame's vertical blanking.
class VgaMonitor {
 public:
  // What the registers hold now (the testbench's writes); enabling latches
  // them at once, as the RTL does.
  void set_regs(bool enable, bool letterbox, uint32_t base) {
    if (enable && !enable_) {
      latched_letterbox_ = letterbox;
      latched_base_ = base;
      locked_ = false;
      capturing_ = false;
    }
    if (!enable) {
      locked_ = false;
      capturing_ = false;
      since_disable_ = 0;
    }
    enable_ = enable;
    letterbox_ = letterbox;
    base_ = base;
  }
  // Lines cut short (black to their end) are accepted, and counted, in the
  // frames compared while this is on.
  void allow_cut(bool on) { allow_cut_ = on; }
  int frames_compared() const { return frames_; }
  int frames_with_cut_lines() const { return cut_frames_; }
  int cut_lines() const { return cut_lines_total_; }
  int last_cut_lines() const { return last_cut_; }
  const std::vector<uint8_t> &picture() const { return picture_; }
  bool has_picture() const { return have_picture_; }
  int frames_letterbox() const { return frames_lb_; }

  // After a clk_i edge: `before` are the outputs before it.
  template <class T> void after_edge(T *top, const VgaPins &before, AxiMemory &mem) {
    VgaPins now = vga_pins(top);
    if (!top->rst_ni) return;
    if (now.sync_n) fail("VGA: sync_n high");
    bool rising = now.clk && !before.clk;
    if (rising) {
      // The DAC latches at this edge, enabled or not: the outputs did not
      // change with it.
      if (!(now == before)) fail("VGA: outputs changed on the rising edge of vga_clk");
      dac_ = now;
      since_rise_ = 0;
    } else if (++since_rise_ > 4 && !stopped_reported_) {
      stopped_reported_ = true;
      fail("VGA: vga_clk stopped (%s): the DAC keeps its last pixel", enable_ ? "enabled" : "disabled");
    }
    if (!enable_) {
      ++since_disable_;
      if (since_disable_ > 4 && (now.blank_n || now.r || now.g || now.b || !now.hs || !now.vs))
        fail("VGA: disabled, yet outputs not blank/black with syncs inactive");
      // What the monitor shows: the DAC's latched levels, blank and black
      // within two pixel clocks.
      if (since_disable_ > 8 && (dac_.blank_n || dac_.r || dac_.g || dac_.b) && !dac_reported_) {
        dac_reported_ = true;
        fail("VGA: disabled, yet the DAC holds %s %02x%02x%02x", dac_.blank_n ? "unblanked" : "blanked", dac_.r,
             dac_.g, dac_.b);
      }
      return;
    }
    if (rising) sample(now, mem);
  }
  // The DAC's latched levels (R, G, B, BLANK_N as of its last clock edge).
  const VgaPins &dac() const { return dac_; }

 private:
  void sample(const VgaPins &p, AxiMemory &mem) {
    if (!locked_) {
      if (prev_vs_ && !p.vs) {
        locked_ = true;
        k_ = 0;
      }
      prev_vs_ = p.vs;
      if (!locked_) return;
    }
    prev_vs_ = p.vs;
    int htot = g_h.total(), vtot = g_v.total();
    int h = int(k_ % htot);
    int v = int((g_v.visible + g_v.front + k_ / htot) % vtot);
    ++k_;
    int hs_start = g_h.visible + g_h.front, vs_start = g_v.visible + g_v.front;
    bool want_hs = !(h >= hs_start && h < hs_start + g_h.sync);
    bool want_vs = !(v >= vs_start && v < vs_start + g_v.sync);
    bool visible = h < g_h.visible && v < g_v.visible;
    if (p.hs != want_hs || p.vs != want_vs || p.blank_n != visible) {
      if (++timing_errors_ <= 5)
        fail("VGA timing at line %d pixel %d: hs %d vs %d blank_n %d, want %d %d %d", v, h, p.hs, p.vs, p.blank_n,
             want_hs, want_vs, visible);
    }
    if (!visible && (p.r || p.g || p.b)) fail("VGA: RGB not black in blanking at line %d pixel %d", v, h);
    if (v == g_v.visible && h == 0) {
      // Start of vertical blanking: the registers are latched.
      latched_letterbox_ = letterbox_;
      latched_base_ = base_;
    }
    if (v == 0 && h == 0) {
      capturing_ = true;
      frame_letterbox_ = latched_letterbox_;
      frame_base_ = latched_base_;
      grab_.assign(size_t(kDispW) * kDispH * 3, 0);
    }
    if (capturing_ && visible) {
      uint8_t *px = &grab_[(size_t(v) * kDispW + h) * 3];
      px[0] = p.r, px[1] = p.g, px[2] = p.b;
      if (v == g_v.visible - 1 && h == g_h.visible - 1) {
        compare(mem);
        capturing_ = false;
      }
    }
  }

  void compare(AxiMemory &mem) {
    const std::vector<uint8_t> &map = g_map[frame_letterbox_ ? 1 : 0];
    std::vector<uint8_t> want(grab_.size(), 0);
    for (size_t i = 0; i < size_t(kDispW) * kDispH; ++i) {
      uint32_t idx = uint32_t(map[3 * i]) << 16 | uint32_t(map[3 * i + 1]) << 8 | map[3 * i + 2];
      if (idx) memcpy(&want[3 * i], mem.bytes(frame_base_ + (idx - 1) * 3), 3);
    }
    int bad = 0, cut = 0;
    for (int y = 0; y < kDispH; ++y) {
      const uint8_t *g = &grab_[size_t(y) * kDispW * 3], *w = &want[size_t(y) * kDispW * 3];
      int x = 0;
      while (x < kDispW && !memcmp(g + 3 * x, w + 3 * x, 3)) ++x;
      if (x == kDispW) continue;
      bool black_rest = true;
      for (int i = 3 * x; i < kDispW * 3; ++i) black_rest = black_rest && g[i] == 0;
      if (allow_cut_ && black_rest) {
        ++cut;
        continue;
      }
      if (++bad <= 3)
        fail("VGA picture (%s, base 0x%08x) line %d pixel %d: got %02x%02x%02x want %02x%02x%02x",
             frame_letterbox_ ? "letterbox" : "full screen", frame_base_, y, x, g[3 * x], g[3 * x + 1], g[3 * x + 2],
             w[3 * x], w[3 * x + 1], w[3 * x + 2]);
    }
    ++frames_;
    if (frame_letterbox_) ++frames_lb_;
    last_cut_ = cut;
    if (cut) ++cut_frames_, cut_lines_total_ += cut;
    picture_ = grab_;
    have_picture_ = true;
    printf("VGA frame %d (%s, base 0x%08x): %s%s\n", frames_, frame_letterbox_ ? "letterbox" : "full screen",
           frame_base_, bad ? "DIFFERS" : "byte-exact", cut ? (", " + std::to_string(cut) + " lines cut").c_str() : "");
  }

  bool enable_ = false, letterbox_ = false, latched_letterbox_ = false, frame_letterbox_ = false;
  uint32_t base_ = 0, latched_base_ = 0, frame_base_ = 0;
  bool locked_ = false, prev_vs_ = true, capturing_ = false, allow_cut_ = false, have_picture_ = false;
  uint64_t k_ = 0;
  int since_disable_ = 0, timing_errors_ = 0, since_rise_ = 0;
  bool stopped_reported_ = false, dac_reported_ = false;
  VgaPins dac_{};
  int frames_ = 0, frames_lb_ = 0, cut_frames_ = 0, cut_lines_total_ = 0, last_cut_ = 0;
  std::vector<uint8_t> grab_, picture_;
};

class Bench {
 public:
  explicit Bench(uint32_t mem_seed) : top_(new Vrt_top), mem_(mem_seed) {
    top_->clk_i = 0;
    top_->rst_ni = 0;
    top_->avs_read_i = 0;
    top_->avs_write_i = 0;
    top_->avs_address_i = 0;
    top_->avs_writedata_i = 0;
    top_->axm_awready_i = 0;
    top_->axm_wready_i = 0;
    top_->axm_bvalid_i = 0;
    top_->axm_bresp_i = 0;
    top_->axm_arready_i = 0;
    top_->axm_rvalid_i = 0;
    top_->axm_rdata_i = 0;
    top_->axm_rresp_i = 0;
    top_->axm_rlast_i = 0;
    top_->key_n_i = 0xf;  // no key pressed (active low)
    top_->sw_i = 0;
    top_->eval();
    tick();
    tick();
    top_->rst_ni = 1;
    tick();
  }
  ~Bench() { top_->final(); }

  // One clock: inputs (the memory model's too) settle, the handshakes of
  // the rising edge are taken from the outputs as they were, then the edge.
  void tick() {
    mem_.drive(top_.get(), cycles_);
    top_->clk_i = 0;
    top_->eval();
    axi_.sample(top_.get(), mem_.awready(), mem_.wready(), mem_.bvalid(), mem_.arready(), mem_.rvalid());
    mem_.edge(top_.get(), cycles_);
    VgaPins before = vga_pins(top_.get());
    top_->clk_i = 1;
    top_->eval();
    vga_.after_edge(top_.get(), before, mem_);
    ++cycles_;
  }
  void ticks(uint64_t n) {
    for (uint64_t i = 0; i < n; ++i) tick();
  }

  // One Avalon write transfer (no waitrequest).
  void write(uint32_t byte_off, uint32_t value) {
    if (byte_off == kVgaControl) vga_ctl_ = value & 3;
    if (byte_off == kVgaBase) vga_base_ = value & ~7u;
    if (byte_off == kVgaControl || byte_off == kVgaBase)
      vga_.set_regs(vga_ctl_ & kVgaEnable, vga_ctl_ & kVgaLetterbox, vga_base_);
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
  AxiMemory &memory() { return mem_; }
  AxiChecker &checker() { return axi_; }
  VgaMonitor &vga() { return vga_; }
  Vrt_top *top() { return top_.get(); }

 private:
  std::unique_ptr<Vrt_top> top_;
  AxiMemory mem_;
  AxiChecker axi_;
  VgaMonitor vga_;
  uint32_t vga_ctl_ = 0, vga_base_ = 0;
  uint64_t cycles_ = 0;
};

int g_errors = 0;
int g_max_errors = 20;

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
  expect_eq("ID", b.read(kId), kIdValue);
  expect_eq("FRAME_BASE after reset", b.read(kFrameBase), 0);
  expect_eq("FRAME_STATUS after reset", b.read(kFrameStatus), 0);
  expect_eq("ROWS_DONE after reset", b.read(kRowsDone), 0);
  expect_eq("FRAME_CONTROL reads 0", b.read(kFrameControl), 0);
  expect_eq("CONTROL reads 0", b.read(kControl), 0);
  expect_eq("BUILD_ID", b.read(kBuildIdOffset), kBuildId);
  b.write(kBuildIdOffset, 0xffffffffu);
  expect_eq("BUILD_ID ignores writes", b.read(kBuildIdOffset), kBuildId);
  expect_eq("unmapped 0x50", b.read(0x50), 0);
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
  expect_eq("ID ignores writes", b.read(kId), kIdValue);
  b.write(kFrameBase, 0x12345677u);
  expect_eq("FRAME_BASE keeps bits 31:3", b.read(kFrameBase), 0x12345670u);
  b.write(kFrameStatus, 0xffffffffu);
  b.write(kRowsDone, 0xffffffffu);
  expect_eq("FRAME_STATUS ignores writes", b.read(kFrameStatus), 0);
  expect_eq("ROWS_DONE ignores writes", b.read(kRowsDone), 0);
  b.write(kFrameControl, kClearDone);
  expect_eq("frame clear when idle", b.read(kFrameStatus), 0);
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

// ---- Frame mode ------------------------------------------------------------

// The golden frame as the wire bytes the DMA must write: R, G, B per pixel.
std::vector<uint8_t> wire_bytes(const Golden &g) {
  std::vector<uint8_t> out;
  out.reserve(kFrameBytes);
  for (uint32_t w : g.words) {
    out.push_back(uint8_t(w >> 16));
    out.push_back(uint8_t(w >> 8));
    out.push_back(uint8_t(w));
  }
  return out;
}

struct FrameRun {
  uint64_t cycles;  // start write to busy seen clear
  uint32_t status, rows;
};

// Clocks without any write-channel transfer after which a busy frame
// counts as deadlocked: above the DMA's own limit of two stall periods
// (2 * 2^17 clocks, hal-avalon map.rs FRAME_STALL_CYCLES), so the DMA's
// stall handling always gets its chance first.
constexpr uint64_t kDeadlockCycles = 300000;
constexpr uint64_t kStallCycles = 1u << 17;

// Poll a frame as the firmware does: ROWS_DONE, then FRAME_STATUS, until
// busy clears. Every ROWS_DONE value is checked against the rows whose
// write responses the memory has sent. A frame with no write-channel
// transfer for kDeadlockCycles fails as a deadlock.
FrameRun poll_frame(Bench &b, uint64_t t0) {
  uint32_t last = 0, status = 0;
  AxiMemory &m = b.memory();
  for (;;) {
    uint32_t rows = b.read(kRowsDone);
    int landed = m.landed_rows();
    if (int(rows) > landed) fail("ROWS_DONE %u ahead of the data: %d rows landed", rows, landed);
    if (rows < last) fail("ROWS_DONE went back from %u to %u", last, rows);
    last = rows;
    status = b.read(kFrameStatus);
    if (!(status & kFrameBusy)) return FrameRun{b.cycles() - t0, status, b.read(kRowsDone)};
    uint64_t since = b.cycles() - std::max(m.last_transfer(), t0);
    if (since > kDeadlockCycles) {
      fail("deadlock under the %s slave: no AXI write transfer for %llu clocks (ROWS_DONE %u)",
           slave_name(m.behaviour()), (unsigned long long)since, last);
      return FrameRun{b.cycles() - t0, status, last};
    }
  }
}

// One frame at `base`.
FrameRun run_frame(Bench &b, uint32_t base, const int32_t light[3]) {
  b.memory().begin_frame(base);
  b.write(kFrameBase, base);
  b.write(kLightX, light_reg(light[0]));
  b.write(kLightY, light_reg(light[1]));
  b.write(kLightZ, light_reg(light[2]));
  uint64_t t0 = b.cycles();
  b.write(kFrameControl, kStart);
  return poll_frame(b, t0);
}

// A whole frame through the DMA under back-pressure: bytes equal the
// golden frame, nothing outside it written.
uint64_t check_frame_dma(Bench &b, const Golden &g, uint32_t base, Slave slave, int aw_stall, int w_stall,
                         int b_delay) {
  const uint8_t kGuard = 0xa5;
  AxiMemory &m = b.memory();
  m.fill(kGuard);
  m.set_behaviour(slave);
  m.set_pressure(aw_stall, w_stall, b_delay);
  FrameRun r = run_frame(b, base, g.light);
  expect_eq("FRAME_STATUS after a frame", r.status, kFrameDone);
  expect_eq("ROWS_DONE after a frame", r.rows, kHeight);
  std::vector<uint8_t> want = wire_bytes(g);
  const uint8_t *got = m.bytes(base);
  int bad = 0;
  for (uint32_t i = 0; i < kFrameBytes; ++i) {
    if (got[i] != want[i]) {
      if (++bad <= 5) fail("frame DMA %s byte %u (row %u): got %02x want %02x", g.path.c_str(), i, i / kRowBytes, got[i], want[i]);
    }
  }
  for (uint32_t a : {base - 64, base - 1, base + kFrameBytes, base + kFrameBytes + 63}) {
    if (*m.bytes(a) != kGuard) fail("frame DMA wrote outside the frame at 0x%08x", a);
  }
  if (!m.quiet()) fail("the %s slave still holds bursts, beats or responses after the frame", slave_name(slave));
  printf("frame DMA light raw (%d, %d, %d) at 0x%08x, %s slave, stalls AW %d%% W %d%%, B delay <= %d: %d of %u bytes differ, %llu cycles\n",
         g.light[0], g.light[1], g.light[2], base, slave_name(slave), aw_stall, w_stall, b_delay, bad, kFrameBytes,
         (unsigned long long)r.cycles);
  return r.cycles;
}

void wait_frame_idle(Bench &b) {
  for (int i = 0; i < 5000000; ++i)
    if (!(b.read(kFrameStatus) & kFrameBusy)) return;
  fail("frame never finished");
}

// Bus errors, starts while busy, a row start during a frame.
void check_frame_semantics(Bench &b, const Golden &g) {
  AxiMemory &m = b.memory();
  m.set_pressure(10, 10, 8);
  // A write error in row 100: error set, done not, the count frozen at 100.
  const uint32_t base = kMemBase + 0x1000;
  m.set_error_range(base + 100 * kRowBytes + 8, 8);
  FrameRun r = run_frame(b, base, g.light);
  expect_eq("FRAME_STATUS after a bus error", r.status, kFrameError);
  expect_eq("ROWS_DONE stops before the failed row", r.rows, 100);
  m.set_error_range(0, 0);
  // The next frame clears the error.
  b.write(kFrameControl, kStart);
  expect_eq("a new frame clears the error", b.read(kFrameStatus) & (kFrameError | kFrameDone), 0);
  wait_frame_idle(b);
  expect_eq("clean frame after the error", b.read(kFrameStatus), kFrameDone);
  b.write(kFrameControl, kClearDone);
  expect_eq("frame clear_done", b.read(kFrameStatus), 0);

  // A frame start while busy and a row start during a frame are ignored.
  b.write(kControl, kClearDone);
  m.begin_frame(base);
  b.write(kFrameControl, kStart);
  b.write(kFrameBase, base + 0x100000);
  b.write(kFrameControl, kStart);
  b.write(kControl, kStart);
  expect_eq("STATUS busy during a frame", b.read(kStatus) & kBusy, kBusy);
  wait_frame_idle(b);
  expect_eq("one frame only", b.read(kRowsDone), kHeight);
  expect_eq("no row ran during the frame", b.read(kStatus), 0);
  b.write(kFrameBase, base);
  printf("frame semantics checks done\n");
}

// The rows of the golden frame that ROWS_DONE covers hold its bytes.
int compare_landed_rows(AxiMemory &m, const Golden &g, uint32_t base, uint32_t rows) {
  std::vector<uint8_t> want = wire_bytes(g);
  const uint8_t *got = m.bytes(base);
  int bad = 0;
  for (uint32_t i = 0; i < rows * kRowBytes; ++i)
    if (got[i] != want[i] && ++bad <= 5) fail("landed row %u byte %u: got %02x want %02x", i / kRowBytes, i, got[i], want[i]);
  return bad;
}

// Nothing is written, and nothing changes state, while the accelerator
// sits idle for `clocks`.
void expect_memory_still(Bench &b, const char *what, uint32_t status, int clocks) {
  std::vector<uint8_t> snapshot = b.memory().all();
  for (int i = 0; i < clocks; ++i) b.tick();
  expect_eq(what, b.read(kFrameStatus), status);
  if (b.memory().all() != snapshot) fail("%s: memory written after the frame went idle", what);
}

// FRAME_CONTROL abort in the middle of a frame: busy clears with aborted
// set (neither done nor error), ROWS_DONE keeps the rows that landed and
// they hold the model's bytes, the slave holds no burst, beat or response,
// nothing is written afterwards, and row mode and the next frame work.
void check_frame_abort(Bench &b, const Golden &g, Slave slave) {
  AxiMemory &m = b.memory();
  m.fill(0x3c);
  m.set_behaviour(slave);
  m.set_pressure(20, 20, 30);
  const uint32_t base = kMemBase + 0x2008;
  m.begin_frame(base);
  b.write(kFrameBase, base);
  b.write(kLightX, light_reg(g.light[0]));
  b.write(kLightY, light_reg(g.light[1]));
  b.write(kLightZ, light_reg(g.light[2]));
  b.write(kFrameControl, kStart);
  uint32_t before = 0;
  for (int i = 0; i < 1000000 && before < 50; ++i) before = b.read(kRowsDone);
  b.write(kFrameControl, kAbort);
  uint64_t t0 = b.cycles();
  FrameRun r = poll_frame(b, t0);
  expect_eq("FRAME_STATUS after an abort", r.status, kFrameAborted);
  if (r.rows < before || r.rows >= uint32_t(kHeight)) fail("ROWS_DONE %u after an abort at %u", r.rows, before);
  if (!m.quiet()) fail("the %s slave still holds bursts after the abort went idle", slave_name(slave));
  compare_landed_rows(m, g, base, r.rows);
  expect_memory_still(b, "after an abort", kFrameAborted, 20000);
  printf("abort under the %s slave: at ROWS_DONE %u, idle %llu clocks later with ROWS_DONE %u\n", slave_name(slave),
         before, (unsigned long long)r.cycles, r.rows);
  uint32_t row[kWidth];
  run_row(b, 90, g.light, row);
  compare_row(g, 90, row, "row mode after an abort");
  check_frame_dma(b, g, base, slave, 10, 10, 10);
}

// A memory that stops answering: write responses lost (the port accepts
// bursts and never answers), or no handshake at all (a port held in
// reset). The frame ends by itself with error and aborted set, within two
// stall periods of the last transfer, ROWS_DONE counting only rows that
// landed; row mode works at once and the next frame is byte-exact.
void check_frame_stall(Bench &b, const Golden &g, bool dead) {
  AxiMemory &m = b.memory();
  const char *what = dead ? "a port that answers nothing" : "lost write responses";
  m.fill(0x5a);
  m.set_behaviour(Slave::kPlatformDesigner);
  m.set_pressure(10, 10, 8);
  if (dead) {
    m.set_dead(true);
    b.checker().allow_withdraw(true);
  } else {
    m.set_lose_responses(true);
  }
  const uint32_t base = kMemBase + 0x1000;
  FrameRun r = run_frame(b, base, g.light);
  uint64_t after_last = b.cycles() - m.last_transfer();
  expect_eq((std::string("FRAME_STATUS with ") + what).c_str(), r.status, kFrameError | kFrameAborted);
  expect_eq((std::string("ROWS_DONE with ") + what).c_str(), r.rows, 0);
  if (after_last > 2 * kStallCycles + 2000)
    fail("%s: idle %llu clocks after the last transfer, beyond two stall periods", what, (unsigned long long)after_last);
  expect_memory_still(b, what, kFrameError | kFrameAborted, 1000);
  if (dead) {
    m.set_dead(false);
    b.checker().allow_withdraw(false);
  } else {
    m.set_lose_responses(false);
  }
  printf("frame with %s: ended with error and aborted after %llu clocks, %llu after the last transfer\n", what,
         (unsigned long long)r.cycles, (unsigned long long)after_last);
  uint32_t row[kWidth];
  run_row(b, 45, g.light, row);
  compare_row(g, 45, row, "row mode after a stalled frame");
  check_frame_dma(b, g, base, Slave::kPlatformDesigner, 10, 10, 10);
}


// ---- VGA scan-out and board I/O ----------------------------------------------

constexpr uint64_t kVgaFrameClocks = 800ull * 525 * 2;  // hal-avalon VGA_FRAME_CLOCKS
// From the end of one compared picture to the middle of the next.
constexpr uint64_t kToMidFrame = 2ull * 800 * (525 - 480 + 240);

// Clocks until the monitor has compared `n` more pictures.
void run_vga_frames(Bench &b, int n) {
  int target = b.vga().frames_compared() + n;
  uint64_t limit = b.cycles() + uint64_t(n + 2) * kVgaFrameClocks;
  while (b.vga().frames_compared() < target && b.cycles() < limit) b.tick();
  if (b.vga().frames_compared() < target) fail("VGA: fewer than %d pictures in %d frame times", n, n + 2);
}

bool load_map(const std::string &path, std::vector<uint8_t> &out) {
  std::ifstream in(path, std::ios::binary);
  out.assign(size_t(kDispW) * kDispH * 3, 0);
  if (!in.read(reinterpret_cast<char *>(out.data()), std::streamsize(out.size()))) {
    fprintf(stderr, "%s: cannot read a %dx%d RGB888 picture\n", path.c_str(), kDispW, kDispH);
    return false;
  }
  return true;
}

bool write_ppm(const std::string &path, const std::vector<uint8_t> &rgb) {
  FILE *f = fopen(path.c_str(), "wb");
  if (!f) return false;
  fprintf(f, "P6\n%d %d\n255\n", kDispW, kDispH);
  bool ok = fwrite(rgb.data(), 1, rgb.size(), f) == rgb.size();
  return fclose(f) == 0 && ok;
}

void put_frame(AxiMemory &m, uint32_t base, const Golden &g) {
  std::vector<uint8_t> bytes = wire_bytes(g);
  memcpy(m.bytes(base), bytes.data(), bytes.size());
}

constexpr uint32_t kVgaA = kMemBase + 0x200008, kVgaB = kMemBase + 0x280010;

// The frames counter equals the pictures the monitor saw since enable
// (read a little after the picture, once blanking has started).
void expect_vga_count(Bench &b, int since_enable, const char *what) {
  b.ticks(400);
  expect_eq(what, b.read(kVgaStatus) & 0xffff, uint32_t(since_enable) & 0xffff);
}

void check_vga(Bench &b, const std::vector<Golden> &goldens) {
  AxiMemory &m = b.memory();
  VgaMonitor &mon = b.vga();
  const Golden &ga = goldens[0], &gb = goldens[goldens.size() > 1 ? 1 : 0];
  // Registers: reset values, widths, nothing enabled by readback tests.
  expect_eq("VGA_CONTROL after reset", b.read(kVgaControl), 0);
  expect_eq("VGA_BASE after reset", b.read(kVgaBase), 0);
  expect_eq("VGA_STATUS after reset", b.read(kVgaStatus), 0);
  b.write(kVgaControl, 0xfffffffeu);
  expect_eq("VGA_CONTROL keeps bits 1:0", b.read(kVgaControl), kVgaLetterbox);
  b.write(kVgaControl, 0);
  b.write(kVgaBase, 0x12345677u);
  expect_eq("VGA_BASE keeps bits 31:3", b.read(kVgaBase), 0x12345670u);
  b.write(kVgaStatus, 0xffffffffu);
  expect_eq("VGA_STATUS W1C when clear", b.read(kVgaStatus), 0);

  m.set_behaviour(Slave::kPlatformDesigner);
  m.set_pressure(20, 20, 20);
  m.set_read_pressure(30, 30, 40);
  put_frame(m, kVgaA, ga);
  put_frame(m, kVgaB, gb);
  uint64_t t0 = b.cycles();
  int at_enable = mon.frames_compared();
  b.write(kVgaBase, kVgaA);
  b.write(kVgaControl, kVgaEnable);
  expect_eq("VGA_STATUS right after enable", b.read(kVgaStatus), 0);
  // Full screen, two pictures.
  run_vga_frames(b, 2);
  expect_vga_count(b, mon.frames_compared() - at_enable, "VGA_STATUS frames, full screen");
  // Letterbox chosen in the middle of a frame: that frame stays full
  // screen, the next two are letterboxed.
  b.ticks(kToMidFrame);
  int lb0 = mon.frames_letterbox();
  b.write(kVgaControl, kVgaEnable | kVgaLetterbox);
  run_vga_frames(b, 3);
  if (mon.frames_letterbox() - lb0 != 2) fail("VGA: %d letterboxed pictures, want 2", mon.frames_letterbox() - lb0);
  // VGA_BASE changed in the middle of a frame: the old frame whole, then
  // the new one whole (the monitor compares each picture with the frame at
  // the base latched at its vertical blanking).
  b.write(kVgaControl, kVgaEnable);
  run_vga_frames(b, 1);
  b.ticks(kToMidFrame);
  b.write(kVgaBase, kVgaB);
  run_vga_frames(b, 2);
  expect_vga_count(b, mon.frames_compared() - at_enable, "VGA_STATUS frames after the base change");
  expect_eq("VGA_STATUS no underrun so far", b.read(kVgaStatus) & kVgaUnderrun, 0);
  uint64_t clean_clocks = b.cycles() - t0;

  // A memory stall that starves the reader: lines cut, underrun set; W1C
  // clears it; the next picture is right again.
  b.ticks(kToMidFrame);
  m.set_read_stall(true);
  b.ticks(20000);
  m.set_read_stall(false);
  mon.allow_cut(true);
  run_vga_frames(b, 1);
  mon.allow_cut(false);
  int cut = mon.last_cut_lines();
  if (cut == 0) fail("VGA: a 20,000-clock read stall cut no line");
  expect_eq("VGA_STATUS underrun after a stall", b.read(kVgaStatus) & kVgaUnderrun, kVgaUnderrun);
  b.write(kVgaStatus, kVgaUnderrun);
  expect_eq("VGA_STATUS underrun W1C", b.read(kVgaStatus) & kVgaUnderrun, 0);
  run_vga_frames(b, 1);
  expect_eq("VGA_STATUS no underrun in the next frame", b.read(kVgaStatus) & kVgaUnderrun, 0);
  printf("VGA underrun test: a 20,000-clock read stall cut %d lines of one picture, underrun set, W1C cleared; next picture byte-exact\n",
         cut);

  // A read answered SLVERR (frame B, mid row 100): not shown, the rest of
  // that picture cut like an underrun, read error and underrun set; the
  // next picture byte-exact. (Without RRESP the beat's data, 0xdeadbeef,
  // would be on screen.)
  m.set_read_error_range(kVgaB + 100 * kRowBytes + 480, 8);
  mon.allow_cut(true);
  run_vga_frames(b, 1);
  mon.allow_cut(false);
  m.set_read_error_range(0, 0);
  int err_cut = mon.last_cut_lines();
  if (err_cut == 0) fail("VGA: a SLVERR beat cut no line");
  expect_eq("VGA_STATUS read error and underrun after SLVERR", b.read(kVgaStatus) & (kVgaReadError | kVgaUnderrun),
            kVgaReadError | kVgaUnderrun);
  b.write(kVgaStatus, kVgaReadError | kVgaUnderrun);
  run_vga_frames(b, 1);
  expect_eq("VGA_STATUS clean after the SLVERR picture", b.read(kVgaStatus) & (kVgaReadError | kVgaUnderrun | kVgaStall), 0);
  printf("VGA read error test: one SLVERR beat, %d lines cut from it on, read error and underrun set; next picture byte-exact\n",
         err_cut);

  // A read port that never answers (held in reset): after the stall limit
  // the reader withdraws its request and forgets its bursts (stall bit);
  // once the port is back, the next whole picture is byte-exact.
  b.ticks(kToMidFrame);
  m.set_read_dead(true);
  b.checker().allow_withdraw(true);
  mon.allow_cut(true);
  b.ticks(kVgaStallCycles + kVgaStallCycles / 2);
  uint32_t dead_status = b.read(kVgaStatus);
  m.set_read_dead(false);
  b.checker().forget_reads();
  b.checker().allow_withdraw(false);
  run_vga_frames(b, 1);
  mon.allow_cut(false);
  expect_eq("VGA_STATUS stall and underrun with a dead read port", dead_status & (kVgaStall | kVgaUnderrun),
            kVgaStall | kVgaUnderrun);
  b.write(kVgaStatus, kVgaStall | kVgaUnderrun | kVgaReadError);
  run_vga_frames(b, 1);
  expect_eq("VGA_STATUS clean once the port is back", b.read(kVgaStatus) & (kVgaReadError | kVgaUnderrun | kVgaStall), 0);
  printf("VGA stall-limit test: a read port dead for %llu clocks, stall and underrun set; the next picture byte-exact\n",
         (unsigned long long)(kVgaStallCycles + kVgaStallCycles / 2));

  // Frame DMA and scan-out at once: two frames rendered into memory
  // while the VGA shows frame B; both byte-exact.
  int before = mon.frames_compared();
  const uint32_t dma_base = kMemBase + 0x1000;
  for (int i = 0; i < 2; ++i) {
    const Golden &g = goldens[size_t(i) % goldens.size()];
    FrameRun r = run_frame(b, dma_base, g.light);
    expect_eq("FRAME_STATUS, frame DMA during scan-out", r.status, kFrameDone);
    std::vector<uint8_t> want = wire_bytes(g);
    if (memcmp(m.bytes(dma_base), want.data(), want.size()))
      fail("frame DMA during scan-out: bytes differ from the model's frame");
    printf("frame DMA during scan-out: light raw (%d, %d, %d), %llu cycles, byte-exact\n", g.light[0], g.light[1],
           g.light[2], (unsigned long long)r.cycles);
  }
  run_vga_frames(b, 1);
  expect_eq("VGA_STATUS no underrun with the frame DMA", b.read(kVgaStatus) & kVgaUnderrun, 0);
  printf("VGA pictures during or right after the frame DMA: %d\n", mon.frames_compared() - before);

  // Disabled in the middle of a picture: blank and black on the pins and
  // in the DAC, which latches them on the still-running vga_clk (the
  // monitor checks every clock); enabling again clears VGA_STATUS and
  // shows the frame at once.
  b.ticks(kToMidFrame + 2 * 320);
  VgaPins lit = mon.dac();
  b.write(kVgaControl, 0);
  b.ticks(5000);
  if (!lit.blank_n) fail("VGA: the disable test did not start on a visible pixel");
  printf("VGA disabled mid-picture: the DAC held %02x%02x%02x, then blank and black with vga_clk running\n", lit.r,
         lit.g, lit.b);
  b.write(kVgaStatus, kVgaUnderrun);
  b.write(kVgaControl, kVgaEnable | kVgaLetterbox);
  expect_eq("VGA_STATUS cleared by enable", b.read(kVgaStatus), 0);
  run_vga_frames(b, 1);
  b.write(kVgaControl, 0);
  b.ticks(100);
  m.set_read_pressure(0, 0, 0);
  printf("VGA monitor: %d pictures compared (%d letterboxed), %d with cut lines (%d lines) under a stall, an error or a dead port; %llu read bursts, %llu beats, at most %d in flight (declared %d); timing checked at every pixel; %.1f Mclocks of clean scan-out\n",
         mon.frames_compared(), mon.frames_letterbox(), mon.frames_with_cut_lines(), mon.cut_lines(),
         (unsigned long long)m.read_bursts(), (unsigned long long)m.read_beats(), b.checker().max_reads_in_flight(),
         kReadIssuing, double(clean_clocks) / 1e6);
}

void check_board_io(Bench &b) {
  Vrt_top *t = b.top();
  // Dark after reset.
  expect_eq("LEDR pins after reset", t->ledr_o, 0);
  for (uint32_t hx : {t->hex0_n_o, t->hex1_n_o, t->hex2_n_o, t->hex3_n_o, t->hex4_n_o, t->hex5_n_o})
    expect_eq("HEX pins after reset (active low, dark)", hx, 0x7f);
  expect_eq("KEYS with no key", b.read(kKeys), 0);
  // Switches, synchronised.
  t->sw_i = 0x2a5;
  b.ticks(3);
  expect_eq("SWITCHES", b.read(kSwitches), 0x2a5);
  t->sw_i = 0x15a;
  b.ticks(3);
  expect_eq("SWITCHES after a change", b.read(kSwitches), 0x15a);
  b.write(kSwitches, 0);
  expect_eq("SWITCHES ignores writes", b.read(kSwitches), 0x15a);
  // LEDs and HEX follow the registers; HEX inverted on the pins.
  b.write(kLeds, 0xffffffffu);
  expect_eq("LEDS keeps 10 bits", b.read(kLeds), 0x3ff);
  expect_eq("LEDR pins", t->ledr_o, 0x3ff);
  b.write(kLeds, 0x155);
  expect_eq("LEDR pins follow", t->ledr_o, 0x155);
  b.write(kHexLo, 0xffffffffu);
  expect_eq("HEX_LO keeps 4 x 7 bits", b.read(kHexLo), 0x7f7f7f7fu);
  b.write(kHexLo, 0x01020408u);
  b.write(kHexHi, 0x12345678u);
  expect_eq("HEX_HI keeps 2 x 7 bits", b.read(kHexHi), 0x5678u);
  const uint32_t want_pins[6] = {0x77, 0x7b, 0x7d, 0x7e, 0x07, 0x29};
  const uint32_t got_pins[6] = {t->hex0_n_o, t->hex1_n_o, t->hex2_n_o, t->hex3_n_o, t->hex4_n_o, t->hex5_n_o};
  for (int i = 0; i < 6; ++i) expect_eq("HEX pin segments (0 = lit)", got_pins[i], want_pins[i]);
  // Keys: KEY1 bounces, then is held; it shows only after the debounce
  // time of a stable level, with its sticky went-down bit.
  for (int i = 0; i < 10; ++i) {
    t->key_n_i = (i & 1) ? 0xf : 0xd;
    b.ticks(500 + 300 * i);
  }
  t->key_n_i = 0xd;  // held down from here
  b.ticks(kKeyDebounce - 20);
  expect_eq("KEYS before the debounce time", b.read(kKeys), 0);
  b.ticks(40);
  expect_eq("KEYS after the debounce time", b.read(kKeys), 0x22);
  b.write(kKeys, 0x0f);  // down bits are not W1C
  expect_eq("KEYS down bits ignore writes", b.read(kKeys), 0x22);
  // A short release (bounce) does not show; a long one does.
  t->key_n_i = 0xf;
  b.ticks(kKeyDebounce / 2);
  t->key_n_i = 0xd;
  b.ticks(kKeyDebounce / 2 + 100);
  expect_eq("KEYS after a short release", b.read(kKeys), 0x22);
  t->key_n_i = 0xf;
  b.ticks(kKeyDebounce + 40);
  expect_eq("KEYS after release: sticky stays", b.read(kKeys), 0x20);
  b.write(kKeys, 0x20);
  expect_eq("KEYS went-down W1C", b.read(kKeys), 0);
  printf("board I/O: switches, LEDs, HEX (inverted pins), keys debounced over %u clocks with a bouncing KEY1: checked\n",
         kKeyDebounce);
}

}  // namespace

int main(int argc, char **argv) {
  Verilated::commandArgs(argc, argv);
  // Reports and mismatches (stderr) in the order they happen.
  setvbuf(stdout, nullptr, _IOLBF, 0);
  std::vector<std::string> frames;
  std::string extra;
  bool dma_only = false, vga_only = false, letterbox = false;
  std::string map_full, map_letterbox, vga_out;
  uint32_t mem_seed = 12345;  // the memory model's stalls and delays
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--frame") && i + 1 < argc) frames.push_back(argv[++i]);
    else if (!strcmp(argv[i], "--extra") && i + 1 < argc) extra = argv[++i];
    else if (!strcmp(argv[i], "--max-errors") && i + 1 < argc) g_max_errors = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--dma-only")) dma_only = true;
    else if (!strcmp(argv[i], "--vga-map") && i + 2 < argc) map_full = argv[++i], map_letterbox = argv[++i];
    else if (!strcmp(argv[i], "--vga-timing") && i + 1 < argc) {
      if (sscanf(argv[++i], "%d,%d,%d,%d,%d,%d,%d,%d", &g_h.visible, &g_h.front, &g_h.sync, &g_h.back, &g_v.visible,
                 &g_v.front, &g_v.sync, &g_v.back) != 8) {
        fprintf(stderr, "--vga-timing: eight numbers\n");
        return 2;
      }
    } else if (!strcmp(argv[i], "--vga-only")) vga_only = true;
    else if (!strcmp(argv[i], "--letterbox")) letterbox = true;
    else if (!strcmp(argv[i], "--vga-out") && i + 1 < argc) vga_out = argv[++i];
    else if (!strcmp(argv[i], "--mem-seed") && i + 1 < argc) mem_seed = uint32_t(strtoul(argv[++i], nullptr, 0));
    else if (argv[i][0] != '+') {
      fprintf(stderr,
              "usage: %s [--frame FILE]... [--extra FILE] [--max-errors N] [--dma-only] [--mem-seed N] [--vga-map FULL LETTERBOX]\n"
              "       [--vga-timing H,HFP,HS,HBP,V,VFP,VS,VBP] [--vga-only [--letterbox] --vga-out PPM]\n",
              argv[0]);
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
  if (!map_full.empty() && !(load_map(map_full, g_map[0]) && load_map(map_letterbox, g_map[1]))) return 2;
  if (vga_only) {
    // The simulated monitor's picture of the first frame (cargo xtask vga).
    if (goldens.empty() || map_full.empty()) {
      fprintf(stderr, "--vga-only needs --frame and --vga-map\n");
      return 2;
    }
    Bench bench(mem_seed);
    bench.memory().set_read_pressure(20, 20, 30);
    put_frame(bench.memory(), kVgaA, goldens[0]);
    bench.write(kVgaBase, kVgaA);
    bench.write(kVgaControl, kVgaEnable | (letterbox ? kVgaLetterbox : 0));
    run_vga_frames(bench, 2);
    if (!vga_out.empty() && !write_ppm(vga_out, bench.vga().picture())) {
      fprintf(stderr, "cannot write %s\n", vga_out.c_str());
      return 2;
    }
    printf("VGA monitor: %d pictures compared, %d mismatches\n", bench.vga().frames_compared(), g_errors);
    return g_errors ? 1 : 0;
  }
  Bench bench(mem_seed);
  if (!extra.empty()) {
    Golden ex;
    if (!load_golden(extra, ex)) return 2;
    check_registers(bench, ex, goldens.empty() ? nullptr : &goldens[0]);
  }
  if (!dma_only)
    for (const Golden &g : goldens) check_frame(bench, g);
  // Frame mode: each frame under every slave behaviour, with a different
  // back-pressure and base (8-byte aligned, not always 128-byte aligned)
  // each time; then one run without stalls behind the Platform-Designer-like
  // slave for the cycle count; then the semantics, aborts and stalls.
  const int pressure[][3] = {{30, 40, 40}, {60, 20, 5}, {0, 70, 100}, {50, 50, 20}, {80, 0, 0}, {20, 80, 60}};
  const Slave slaves[] = {Slave::kPlatformDesigner, Slave::kDataFirst, Slave::kAddressFirst};
  int runs = 0;
  for (size_t i = 0; i < goldens.size(); ++i) {
    for (Slave s : slaves) {
      const int *p = pressure[runs % 6];
      check_frame_dma(bench, goldens[i], kMemBase + 0x1000 + uint32_t(runs % 7) * 0x1238, s, p[0], p[1], p[2]);
      ++runs;
    }
  }
  if (!goldens.empty()) {
    uint64_t c = check_frame_dma(bench, goldens[0], kMemBase + 0x1000, Slave::kPlatformDesigner, 0, 0, 0);
    printf("frame mode cycles per frame: %llu\n", (unsigned long long)c);
    printf("frame mode frames/s at 50 MHz: %.1f\n", 50e6 / double(c));
    check_frame_semantics(bench, goldens[0]);
    for (Slave s : slaves) check_frame_abort(bench, goldens[0], s);
    check_frame_stall(bench, goldens[0], false);
    check_frame_stall(bench, goldens[0], true);
    // Row mode still works after frames.
    uint32_t row[kWidth];
    run_row(bench, 180, goldens[0].light, row);
    compare_row(goldens[0], 180, row, "row mode after frames");
    if (!map_full.empty()) {
      check_vga(bench, goldens);
      check_board_io(bench);
    }
    printf("frame-mode runs: %d under %zu slave behaviours, AXI protocol violations: %llu\n", runs + 1,
           sizeof slaves / sizeof slaves[0], (unsigned long long)bench.checker().violations());
  }
  if (g_errors) {
    printf("co-simulation FAILED: %d mismatches\n", g_errors);
    return 1;
  }
  printf("co-simulation passed: %zu frames, every pixel equal to the model\n", goldens.size());
  return 0;
}
