// Stage 3, shade (trace.rs shade_sphere / shade_plane, up to the secondary
// ray): L = normalize(light - p) over the exact 25-bit difference, shared by
// the sphere and the plane (a pixel hits one of them); the sphere's local
// colour shade(SPHERE_BASE, intensity(N . L)); the plane's intensity(L.y);
// and, in parallel with the normalise, the sphere's mirror ray
// r = n - N * (k + k) with k = n . N.
module rt_stage_shade
  import rt_pkg::*;
#(
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic   clk_i,
  input  logic   rst_ni,
  input  vec3_t  light_i,  // latched for the whole row
  input  logic   in_valid_i,
  output logic   in_ready_o,
  input  isect_t in_i,
  output logic   out_valid_o,
  input  logic   out_ready_i,
  output shade_t out_o
);
  localparam int NormLat = normalize_lat(SQRT_BPS, DIV_BPS);
  localparam int Lat = 2 + NormLat + DotLat;
  localparam int MirLat = 4 + FpMulLat;  // r registered at this time

  logic en;
  stage_ctrl #(.LAT(Lat)) u_ctrl (
    .clk_i, .rst_ni, .in_valid_i, .in_ready_o, .out_valid_o, .out_ready_i, .en_o(en)
  );

  // ---- Light vector ----------------------------------------------------
  wvec3_t lv_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      lv_q.x <= wide_t'(light_i.x) - wide_t'(in_i.p.x);
      lv_q.y <= wide_t'(light_i.y) - wide_t'(in_i.p.y);
      lv_q.z <= wide_t'(light_i.z) - wide_t'(in_i.p.z);
    end
  end
  vec3_t ldir;
  q_t llen;
  normalize #(.IN_W(WordBits + 1), .SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_norm (
    .clk_i, .en_i(en), .vx_i(lv_q.x), .vy_i(lv_q.y), .vz_i(lv_q.z),
    .dir_o(ldir), .len_o(llen)
  );

  // ---- Sphere: N . L ------------------------------------------------------
  vec3_t normal_l;
  pipe_delay #(.WIDTH($bits(vec3_t)), .DEPTH(1 + NormLat)) u_normal_l (
    .clk_i, .en_i(en), .d_i(in_i.normal), .q_o(normal_l)
  );
  q_t cos_s;
  vec3_dot u_cos (.clk_i, .en_i(en), .a_i(normal_l), .b_i(ldir), .y_o(cos_s));
  vec3_t ldir_c;
  q_t llen_c;
  pipe_delay #(.WIDTH($bits(vec3_t) + WordBits), .DEPTH(DotLat)) u_ldir_c (
    .clk_i, .en_i(en), .d_i({ldir, llen}), .q_o({ldir_c, llen_c})
  );

  // ---- Sphere: mirror ray ----------------------------------------------
  q_t k;
  vec3_dot u_k (.clk_i, .en_i(en), .a_i(in_i.n), .b_i(in_i.normal), .y_o(k));
  q_t kk_q;
  always_ff @(posedge clk_i) if (en) kk_q <= qadd(k, k);
  vec3_t normal_m, n_m;
  pipe_delay #(.WIDTH($bits(vec3_t)), .DEPTH(DotLat + 1)) u_normal_m (
    .clk_i, .en_i(en), .d_i(in_i.normal), .q_o(normal_m)
  );
  pipe_delay #(.WIDTH($bits(vec3_t)), .DEPTH(DotLat + 1 + FpMulLat)) u_n_m (
    .clk_i, .en_i(en), .d_i(in_i.n), .q_o(n_m)
  );
  vec3_t sc;
  fp_mul u_scx (.clk_i, .en_i(en), .a_i(normal_m.x), .b_i(kk_q), .y_o(sc.x));
  fp_mul u_scy (.clk_i, .en_i(en), .a_i(normal_m.y), .b_i(kk_q), .y_o(sc.y));
  fp_mul u_scz (.clk_i, .en_i(en), .a_i(normal_m.z), .b_i(kk_q), .y_o(sc.z));
  vec3_t r_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      r_q.x <= qsub(n_m.x, sc.x);
      r_q.y <= qsub(n_m.y, sc.y);
      r_q.z <= qsub(n_m.z, sc.z);
    end
  end
  // Elaboration check for simulation and lint only (Quartus never sees it).
  // synthesis translate_off
  generate
  if (MirLat != DotLat + 2 + FpMulLat) begin : g_mirlat_check
    $error("mirror-ray latency bookkeeping is off");
  end
  endgenerate
  // synthesis translate_on
  vec3_t r_a;
  pipe_delay #(.WIDTH($bits(vec3_t)), .DEPTH(Lat - 1 - MirLat)) u_r_a (
    .clk_i, .en_i(en), .d_i(r_q), .q_o(r_a)
  );

  // ---- Side data and output ----------------------------------------------
  coord_t x_a;
  hit_e kind_a;
  vec3_t p_a;
  rgb_t sky_a;
  pipe_delay #(.WIDTH($bits(coord_t) + $bits(hit_e) + $bits(vec3_t) + $bits(rgb_t)),
               .DEPTH(Lat - 1)) u_side (
    .clk_i, .en_i(en), .d_i({in_i.x, in_i.kind, in_i.p, in_i.sky}),
    .q_o({x_a, kind_a, p_a, sky_a})
  );

  always_ff @(posedge clk_i) begin
    if (en) begin
      out_o.x <= x_a;
      out_o.kind <= kind_a;
      out_o.p <= p_a;
      out_o.sky <= sky_a;
      out_o.ldir <= ldir_c;
      out_o.llen <= llen_c;
      out_o.r <= r_a;
      out_o.local_rgb <= shade_rgb(SphereBase, intensity(cos_s));
      out_o.plane_i <= intensity(ldir_c.y);
      out_o.plane_cpos <= ldir_c.y > 0;
    end
  end
endmodule
