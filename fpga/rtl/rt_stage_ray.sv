// Stage 1, compute-ray (trace.rs camera_ray + normalize): the exact integer
// camera direction d through pixel (x, y) and its normalised form n.
//   xs = 2x - 479, ys = 359 - 2y (half pixels, screen up positive)
//   d  = (61 xs, 60 ys - 11 * 800, 11 ys + 60 * 800)   (scene.rs camera basis)
// Constant products are written as shift-adds so they take no DSP block.
module rt_stage_ray
  import rt_pkg::*;
#(
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic clk_i,
  input  logic rst_ni,
  input  logic in_valid_i,
  output logic in_ready_o,
  input  pix_t in_i,
  output logic out_valid_o,
  input  logic out_ready_i,
  output ray_t out_o
);
  localparam int NormLat = normalize_lat(SQRT_BPS, DIV_BPS);
  localparam int Lat = 1 + NormLat;

  logic en;
  stage_ctrl #(.LAT(Lat)) u_ctrl (
    .clk_i, .rst_ni, .in_valid_i, .in_ready_o, .out_valid_o, .out_ready_i, .en_o(en)
  );

  // xs in [-479, 543], ys in [-663, 359] for any 9-bit coordinate: 12 bits.
  typedef logic signed [11:0] hs_t;
  hs_t xs, ys;
  vec3_t d;
  always_comb begin
    xs = (hs_t'(in_i.x) <<< 1) - hs_t'(Width - 1);
    ys = hs_t'(Height - 1) - (hs_t'(in_i.y) <<< 1);
    // 61 = 64 - 4 + 1, 60 = 64 - 4, 11 = 8 + 2 + 1 (CAMERA_RIGHT_X, CAMERA_UP)
    d.x = (q_t'(xs) <<< 6) - (q_t'(xs) <<< 2) + q_t'(xs);
    d.y = (q_t'(ys) <<< 6) - (q_t'(ys) <<< 2) + q_t'(CamFwdY * FocalHalfPixels);
    d.z = (q_t'(ys) <<< 3) + (q_t'(ys) <<< 1) + q_t'(ys) + q_t'(CamFwdZ * FocalHalfPixels);
  end

  // The basis check the shift-adds above rely on.
  // Elaboration check for simulation and lint only (Quartus never sees it).
  // synthesis translate_off
  generate
  if (CamRightX != 61 || CamUpY != 60 || CamUpZ != 11) begin : g_basis_check
    $error("camera basis changed: update the shift-adds");
  end
  endgenerate
  // synthesis translate_on

  vec3_t d_q;
  coord_t x_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      d_q <= d;
      x_q <= in_i.x;
    end
  end

  vec3_t n;
  q_t unused_len;
  normalize #(.IN_W(WordBits), .SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_norm (
    .clk_i, .en_i(en),
    .vx_i(d_q.x), .vy_i(d_q.y), .vz_i(d_q.z),
    .dir_o(n), .len_o(unused_len)
  );

  pipe_delay #(.WIDTH($bits(coord_t) + $bits(vec3_t)), .DEPTH(NormLat)) u_side (
    .clk_i, .en_i(en), .d_i({x_q, d_q}), .q_o({out_o.x, out_o.d})
  );
  assign out_o.n = n;

  /* verilator lint_off UNUSEDSIGNAL */
  logic unused;
  assign unused = ^unused_len;
  /* verilator lint_on UNUSEDSIGNAL */
endmodule
