// C ABI over the Verilated rt_top (fpga/rtl): one bus transaction per call,
// clocked, and an AXI3 memory port that hands every accepted write beat to
// a callback and serves every read burst (the VGA scan-out's) from another
// (the Rust side's memory); the board's keys and switches in, its LEDs and
// 7-segment pins out. See rtl-port/src/lib.rs.
//
// Bus timing follows the Avalon slave exactly as the co-simulation drives it
// (fpga/tb/tb_rt_top.cpp): a write is one clock with write asserted, a read
// one clock with read asserted and readdata taken after it (fixed read
// latency 1). The AXI slave accepts AW and W on every clock and answers B
// one clock after a burst's last beat: OKAY if the callback took every beat,
// SLVERR otherwise. While the Rust memory does not answer
// (`rtl_port_set_answering`), the slave takes nothing and answers nothing,
// as a port held in reset; when it answers again it starts empty. Reads:
// AR accepted on every clock (up to 8 bursts queued), R beats one a clock
// from the first, RRESP SLVERR for bytes the callback could not read.
#include <cstdint>
#include <deque>
#include <memory>

#include "Vrt_top.h"
#include "verilated.h"

extern "C" {
typedef int (*rtl_dma_write_fn)(void *ctx, uint32_t addr, const uint8_t *bytes, uint32_t len);
typedef int (*rtl_dma_read_fn)(void *ctx, uint32_t addr, uint8_t *out, uint32_t len);
}

namespace {

struct Burst {
  uint32_t addr;
  int beats, done;
  bool error;
};

struct Resp {
  uint64_t due;
  uint8_t resp;
};

struct ReadBurst {
  uint32_t addr;
  int beats, done;
};

}  // namespace

struct RtlPort {
  std::unique_ptr<VerilatedContext> ctx;
  std::unique_ptr<Vrt_top> top;
  uint64_t cycles = 0;
  rtl_dma_write_fn dma = nullptr;
  void *dma_ctx = nullptr;
  rtl_dma_read_fn dma_read = nullptr;
  std::deque<Burst> aw;
  std::deque<ReadBurst> ar;
  bool arready = false, rvalid = false;
  std::deque<Resp> b;
  bool bvalid = false;
  bool answering = true;

  RtlPort() : ctx(new VerilatedContext), top(new Vrt_top(ctx.get(), "rt_top")) {}

  void drive() {
    bvalid = answering && !b.empty() && b.front().due <= cycles;
    top->axm_awready_i = answering;
    top->axm_wready_i = answering;
    top->axm_bvalid_i = bvalid;
    top->axm_bresp_i = bvalid ? b.front().resp : 0;
    arready = answering && ar.size() < 8;
    rvalid = answering && !ar.empty();
    uint64_t data = 0;
    bool ok = false;
    if (rvalid) {
      const ReadBurst &r = ar.front();
      uint8_t bytes[8] = {0};
      ok = dma_read && dma_read(dma_ctx, r.addr + 8u * uint32_t(r.done), bytes, 8);
      for (int i = 0; i < 8; ++i) data |= uint64_t(ok ? bytes[i] : 0) << (8 * i);
    }
    top->axm_arready_i = arready;
    top->axm_rvalid_i = rvalid;
    top->axm_rdata_i = data;
    top->axm_rresp_i = rvalid && !ok ? 2 : 0;
    top->axm_rlast_i = rvalid && ar.front().done + 1 == ar.front().beats;
  }

  void edge() {
    if (!top->rst_ni || !answering) return;
    if (top->axm_awvalid_o) aw.push_back(Burst{top->axm_awaddr_o, int(top->axm_awlen_o) + 1, 0, false});
    if (top->axm_wvalid_o && !aw.empty()) {
      Burst &br = aw.front();
      uint32_t at = br.addr + 8u * uint32_t(br.done);
      uint64_t d = top->axm_wdata_o;
      uint8_t strb = top->axm_wstrb_o;
      uint8_t bytes[8];
      for (int i = 0; i < 8; ++i) bytes[i] = uint8_t(d >> (8 * i));
      // Each run of enabled byte lanes is one write.
      for (int i = 0; i < 8;) {
        if (!(strb >> i & 1)) {
          ++i;
          continue;
        }
        int j = i;
        while (j < 8 && (strb >> j & 1)) ++j;
        if (!dma || !dma(dma_ctx, at + uint32_t(i), bytes + i, uint32_t(j - i))) br.error = true;
        i = j;
      }
      if (++br.done == br.beats) {
        b.push_back(Resp{cycles + 1, uint8_t(br.error ? 2 : 0)});
        aw.pop_front();
      }
    }
    if (bvalid && top->axm_bready_o) b.pop_front();
    if (top->axm_arvalid_o && arready) ar.push_back(ReadBurst{top->axm_araddr_o, int(top->axm_arlen_o) + 1, 0});
    if (rvalid && top->axm_rready_o && ++ar.front().done == ar.front().beats) ar.pop_front();
  }

  void tick() {
    drive();
    top->clk_i = 0;
    top->eval();
    edge();
    top->clk_i = 1;
    top->eval();
    ++cycles;
  }

  void reset() {
    aw.clear();
    b.clear();
    ar.clear();
    top->key_n_i = 0xf;  // no key pressed (active low)
    top->sw_i = 0;
    top->avs_read_i = 0;
    top->avs_write_i = 0;
    top->avs_address_i = 0;
    top->avs_writedata_i = 0;
    top->rst_ni = 0;
    tick();
    tick();
    top->rst_ni = 1;
    tick();
  }
};

extern "C" {

RtlPort *rtl_port_new(void) {
  RtlPort *p = new RtlPort;
  p->top->clk_i = 0;
  p->top->eval();
  p->reset();
  return p;
}

void rtl_port_free(RtlPort *p) {
  if (p) {
    p->top->final();
    delete p;
  }
}

void rtl_port_reset(RtlPort *p) { p->reset(); }

void rtl_port_set_answering(RtlPort *p, int on) {
  if (on && !p->answering) {
    p->aw.clear();
    p->b.clear();
    p->ar.clear();
  }
  p->answering = on != 0;
}

void rtl_port_set_dma(RtlPort *p, rtl_dma_write_fn f, void *ctx) {
  p->dma = f;
  p->dma_ctx = ctx;
}

void rtl_port_set_dma_read(RtlPort *p, rtl_dma_read_fn f) { p->dma_read = f; }

// keys: bit n = KEYn held down (the pins are active low); switches: bit n = SWn up.
void rtl_port_set_board_inputs(RtlPort *p, uint32_t keys, uint32_t switches) {
  p->top->key_n_i = ~keys & 0xf;
  p->top->sw_i = switches & 0x3ff;
}

// LEDR9..0 (1 = lit) and HEX0..HEX5 segment pins (active low).
void rtl_port_board_outputs(RtlPort *p, uint16_t *ledr, uint8_t hex_n[6]) {
  p->top->eval();
  *ledr = uint16_t(p->top->ledr_o);
  hex_n[0] = p->top->hex0_n_o;
  hex_n[1] = p->top->hex1_n_o;
  hex_n[2] = p->top->hex2_n_o;
  hex_n[3] = p->top->hex3_n_o;
  hex_n[4] = p->top->hex4_n_o;
  hex_n[5] = p->top->hex5_n_o;
}

void rtl_port_write(RtlPort *p, uint32_t byte_offset, uint32_t value) {
  p->top->avs_address_i = (byte_offset >> 2) & 0x7ff;
  p->top->avs_writedata_i = value;
  p->top->avs_write_i = 1;
  p->tick();
  p->top->avs_write_i = 0;
}

uint32_t rtl_port_read(RtlPort *p, uint32_t byte_offset) {
  p->top->avs_address_i = (byte_offset >> 2) & 0x7ff;
  p->top->avs_read_i = 1;
  p->tick();
  p->top->avs_read_i = 0;
  return p->top->avs_readdata_o;
}

void rtl_port_step(RtlPort *p, uint64_t n) {
  for (uint64_t i = 0; i < n; ++i) p->tick();
}

uint64_t rtl_port_cycles(const RtlPort *p) { return p->cycles; }

}  // extern "C"
