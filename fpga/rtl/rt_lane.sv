// One fully pipelined tracing lane: the four stages in a row with valid/ready
// handshakes between them. It accepts a new pixel every clock and returns
// model::trace_pixel(x, y, light) after rt_pkg::lane_lat(...) cycles.
module rt_lane
  import rt_pkg::*;
#(
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic    clk_i,
  input  logic    rst_ni,
  input  vec3_t   light_i,  // constant while pixels of a row are in flight
  input  logic    in_valid_i,
  output logic    in_ready_o,
  input  pix_t    in_i,
  output logic    out_valid_o,
  input  logic    out_ready_i,
  output px_out_t out_o
);
  logic ray_valid, ray_ready, isect_valid, isect_ready, shade_valid, shade_ready;
  ray_t ray;
  isect_t isect;
  shade_t shade;

  rt_stage_ray #(.SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_ray (
    .clk_i, .rst_ni,
    .in_valid_i, .in_ready_o, .in_i,
    .out_valid_o(ray_valid), .out_ready_i(ray_ready), .out_o(ray)
  );
  rt_stage_intersect #(.SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_isect (
    .clk_i, .rst_ni,
    .in_valid_i(ray_valid), .in_ready_o(ray_ready), .in_i(ray),
    .out_valid_o(isect_valid), .out_ready_i(isect_ready), .out_o(isect)
  );
  rt_stage_shade #(.SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_shade (
    .clk_i, .rst_ni, .light_i,
    .in_valid_i(isect_valid), .in_ready_o(isect_ready), .in_i(isect),
    .out_valid_o(shade_valid), .out_ready_i(shade_ready), .out_o(shade)
  );
  rt_stage_secondary #(.SQRT_BPS(SQRT_BPS), .DIV_BPS(DIV_BPS)) u_sec (
    .clk_i, .rst_ni,
    .in_valid_i(shade_valid), .in_ready_o(shade_ready), .in_i(shade),
    .out_valid_o, .out_ready_i, .out_o
  );
endmodule
