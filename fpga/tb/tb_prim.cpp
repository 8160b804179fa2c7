// Verilator test of the arithmetic primitives against model::arith.
//
// Input: a vector file written by `cargo xtask rtl` (one vector per line, 21
// hexadecimal fields, 32-bit two's complement):
//   a b  va.x va.y va.z  vb.x vb.y vb.z  w.x w.y w.z |
//   fp_mul fp_div fp_sqrt vec3_dot  cross.x cross.y cross.z  ndir.x ndir.y ndir.z nlen
// Vector i is applied at clock i; each output is compared after that
// primitive's latency. Exit status 0 only if every output matched.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "Vprim_top.h"
#include "verilated.h"

namespace {
constexpr int kIn = 11, kOut = 11;
struct Vec {
  int32_t v[kIn + kOut];
};

uint32_t w24(int32_t x) { return uint32_t(x) & 0xffffffu; }
uint32_t w25(int32_t x) { return uint32_t(x) & 0x1ffffffu; }
int32_t sx24(uint32_t x) { return int32_t(x << 8) >> 8; }
// vec3_t packs x in the high word: {x, y, z}, 72 bits as three 32-bit words.
void set_vec3(VlWide<3> &dst, int32_t x, int32_t y, int32_t z) {
  // bit 0..23 = z, 24..47 = y, 48..71 = x
  uint64_t lo = uint64_t(w24(z)) | (uint64_t(w24(y)) << 24) | (uint64_t(w24(x)) << 48);
  dst[0] = uint32_t(lo);
  dst[1] = uint32_t(lo >> 32);
  dst[2] = w24(x) >> 16;
}
void get_vec3(const VlWide<3> &src, int32_t out[3]) {
  uint64_t lo = uint64_t(src[0]) | (uint64_t(src[1]) << 32);
  out[2] = sx24(uint32_t(lo & 0xffffff));
  out[1] = sx24(uint32_t((lo >> 24) & 0xffffff));
  out[0] = sx24(uint32_t(((lo >> 48) & 0xffff) | (uint64_t(src[2] & 0xff) << 16)));
}
}  // namespace

int main(int argc, char **argv) {
  Verilated::commandArgs(argc, argv);
  if (argc < 2) {
    fprintf(stderr, "usage: %s VECTORS\n", argv[0]);
    return 2;
  }
  std::ifstream in(argv[1]);
  std::vector<Vec> vecs;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '/') continue;
    std::istringstream ss(line);
    Vec v{};
    std::string tok;
    int i = 0;
    while (ss >> tok && i < kIn + kOut) {
      if (tok == "|") continue;
      v.v[i++] = int32_t(strtoul(tok.c_str(), nullptr, 16));
    }
    if (i != kIn + kOut) {
      fprintf(stderr, "bad vector line: %s\n", line.c_str());
      return 2;
    }
    vecs.push_back(v);
  }
  if (vecs.empty()) {
    fprintf(stderr, "no vectors in %s\n", argv[1]);
    return 2;
  }
  auto top = std::make_unique<Vprim_top>();
  top->clk_i = 0;
  top->eval();
  const int lat[6] = {top->lat_mul_o, top->lat_div_o, top->lat_sqrt_o,
                      top->lat_dot_o, top->lat_cross_o, top->lat_norm_o};
  const char *names[6] = {"fp_mul", "fp_div", "fp_sqrt", "vec3_dot", "vec3_cross", "normalize"};
  int max_lat = 0;
  for (int l : lat) max_lat = l > max_lat ? l : max_lat;
  long errors = 0, checked[6] = {0, 0, 0, 0, 0, 0};
  const long n = long(vecs.size());
  // Cycle t: apply vector t (if any), clock, then outputs belong to vector
  // t + 1 - lat for each primitive.
  for (long t = 0; t < n + max_lat; ++t) {
    const Vec &v = vecs[size_t(t < n ? t : n - 1)];
    top->a_i = w24(v.v[0]);
    top->b_i = w24(v.v[1]);
    set_vec3(top->va_i, v.v[2], v.v[3], v.v[4]);
    set_vec3(top->vb_i, v.v[5], v.v[6], v.v[7]);
    top->wx_i = w25(v.v[8]);
    top->wy_i = w25(v.v[9]);
    top->wz_i = w25(v.v[10]);
    top->clk_i = 1;
    top->eval();
    top->clk_i = 0;
    top->eval();
    for (int p = 0; p < 6; ++p) {
      long k = t + 1 - lat[p];
      if (k < 0 || k >= n) continue;
      const int32_t *want = &vecs[size_t(k)].v[kIn];
      int32_t got[4] = {0, 0, 0, 0};
      int32_t exp[4] = {0, 0, 0, 0};
      int m = 1;
      switch (p) {
        case 0: got[0] = sx24(top->mul_o); exp[0] = want[0]; break;
        case 1: got[0] = sx24(top->div_o); exp[0] = want[1]; break;
        case 2: got[0] = sx24(top->sqrt_o); exp[0] = want[2]; break;
        case 3: got[0] = sx24(top->dot_o); exp[0] = want[3]; break;
        case 4: get_vec3(top->cross_o, got); for (int i = 0; i < 3; ++i) exp[i] = want[4 + i]; m = 3; break;
        case 5:
          get_vec3(top->ndir_o, got);
          got[3] = sx24(top->nlen_o);
          for (int i = 0; i < 4; ++i) exp[i] = want[7 + i];
          m = 4;
          break;
      }
      ++checked[p];
      for (int i = 0; i < m; ++i) {
        if (got[i] != exp[i]) {
          if (++errors <= 20) {
            const int32_t *a = vecs[size_t(k)].v;
            fprintf(stderr, "MISMATCH %s vector %ld (a %d b %d w %d %d %d) output %d: got %d want %d\n",
                    names[p], k, a[0], a[1], a[8], a[9], a[10], i, got[i], exp[i]);
          }
        }
      }
    }
  }
  for (int p = 0; p < 6; ++p) printf("%-10s latency %2d, %ld vectors\n", names[p], lat[p], checked[p]);
  top->final();
  if (errors) {
    printf("primitive test FAILED: %ld mismatches\n", errors);
    return 1;
  }
  printf("primitive test passed: every output equal to model::arith\n");
  return 0;
}
