// Stage 2, intersect (trace.rs trace_pixel): the unit sphere with the unit
// ray n from EYE, else the plane y = 0 with the exact ray d, else the sky.
// Both tests run in parallel; the sphere wins (it stands on the plane and the
// eye is above it, so its hit is always the nearer one).
//
// Primary-ray constants (EYE = (0, 2, -6), SPHERE_CENTRE = (0, 1, 0)):
//   oc = C - EYE = (0, -1, 6), so b = oc . n = -n.y + 6 n.z and
//   oc x n = (-n.z - 6 n.y, 6 n.x, n.x) exactly (products of whole numbers
//   need no rounding); hit_plane's fp_mul(EYE.y = 2, c) is exactly sat(2c).
module rt_stage_intersect
  import rt_pkg::*;
#(
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic   clk_i,
  input  logic   rst_ni,
  input  logic   in_valid_i,
  output logic   in_ready_o,
  input  ray_t   in_i,
  output logic   out_valid_o,
  input  logic   out_ready_i,
  output isect_t out_o
);
  localparam int SqrtLat = fp_sqrt_lat(SQRT_BPS);
  localparam int DivLat = fp_div_lat(DIV_BPS);
  localparam int SphLat = 5 + DotLat + SqrtLat + FpMulLat;
  localparam int PlnLat = 2 + DivLat;
  localparam int AlignLat = (SphLat > PlnLat) ? SphLat : PlnLat;
  localparam int Lat = AlignLat + 1;

  logic en;
  stage_ctrl #(.LAT(Lat)) u_ctrl (
    .clk_i, .rst_ni, .in_valid_i, .in_ready_o, .out_valid_o, .out_ready_i, .en_o(en)
  );

  // ---- Sphere (hit_sphere(EYE, n)) --------------------------------------
  q_t b1_q;
  vec3_t perp1_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      b1_q      <= qsat(-qext(in_i.n.y) + 6 * qext(in_i.n.z));
      perp1_q.x <= qsat(-qext(in_i.n.z) - 6 * qext(in_i.n.y));
      perp1_q.y <= qsat(6 * qext(in_i.n.x));
      perp1_q.z <= in_i.n.x;
    end
  end

  q_t d2;
  vec3_dot u_d2 (.clk_i, .en_i(en), .a_i(perp1_q), .b_i(perp1_q), .y_o(d2));
  q_t b3;
  pipe_delay #(.WIDTH(WordBits), .DEPTH(DotLat)) u_b3 (
    .clk_i, .en_i(en), .d_i(b1_q), .q_o(b3)
  );

  q_t rad4_q, b4_q;
  logic hit4_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      hit4_q <= (b3 > 0) && (d2 <= QOne);
      rad4_q <= qsub(QOne, d2);
      b4_q   <= b3;
    end
  end

  q_t sq;
  fp_sqrt #(.BPS(SQRT_BPS)) u_sqrt (.clk_i, .en_i(en), .a_i(rad4_q), .y_o(sq));
  q_t b5;
  logic hit5;
  pipe_delay #(.WIDTH(WordBits + 1), .DEPTH(SqrtLat)) u_b5 (
    .clk_i, .en_i(en), .d_i({b4_q, hit4_q}), .q_o({b5, hit5})
  );

  q_t t_q;
  logic hit6_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      t_q    <= qsub(b5, sq);
      hit6_q <= hit5;
    end
  end

  // p = EYE + n * t
  vec3_t n6;
  pipe_delay #(.WIDTH($bits(vec3_t)), .DEPTH(3 + DotLat + SqrtLat)) u_n6 (
    .clk_i, .en_i(en), .d_i(in_i.n), .q_o(n6)
  );
  vec3_t m;
  fp_mul u_mx (.clk_i, .en_i(en), .a_i(n6.x), .b_i(t_q), .y_o(m.x));
  fp_mul u_my (.clk_i, .en_i(en), .a_i(n6.y), .b_i(t_q), .y_o(m.y));
  fp_mul u_mz (.clk_i, .en_i(en), .a_i(n6.z), .b_i(t_q), .y_o(m.z));
  logic hit7;
  pipe_delay #(.WIDTH(1), .DEPTH(FpMulLat)) u_hit7 (
    .clk_i, .en_i(en), .d_i(hit6_q), .q_o(hit7)
  );

  vec3_t p8_q, p9_q, normal9_q;
  logic hit8_q, hit9_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      p8_q.x <= qadd(EyeX, m.x);
      p8_q.y <= qadd(EyeY, m.y);
      p8_q.z <= qadd(EyeZ, m.z);
      hit8_q <= hit7;
      p9_q <= p8_q;
      normal9_q.x <= p8_q.x;  // SPHERE_CENTRE.x = 0
      normal9_q.y <= qsub(p8_q.y, CentreY);
      normal9_q.z <= p8_q.z;  // SPHERE_CENTRE.z = 0
      hit9_q <= hit8_q;
    end
  end

  vec3_t sph_p, sph_normal;
  logic sph_hit;
  pipe_delay #(.WIDTH(2 * $bits(vec3_t) + 1), .DEPTH(AlignLat - SphLat)) u_sph_align (
    .clk_i, .en_i(en), .d_i({p9_q, normal9_q, hit9_q}), .q_o({sph_p, sph_normal, sph_hit})
  );

  // ---- Plane (hit_plane(EYE, d)) ----------------------------------------
  q_t down1_q, ax1_q, az1_q;
  logic pl_hit1_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      pl_hit1_q <= in_i.d.y < 0;
      down1_q   <= qneg(in_i.d.y);
      ax1_q     <= qsat(2 * qext(in_i.d.x));
      az1_q     <= qsat(2 * qext(in_i.d.z));
    end
  end
  q_t qx, qz;
  fp_div #(.BPS(DIV_BPS)) u_divx (.clk_i, .en_i(en), .a_i(ax1_q), .b_i(down1_q), .y_o(qx));
  fp_div #(.BPS(DIV_BPS)) u_divz (.clk_i, .en_i(en), .a_i(az1_q), .b_i(down1_q), .y_o(qz));
  logic pl_hit2;
  pipe_delay #(.WIDTH(1), .DEPTH(DivLat)) u_plhit (
    .clk_i, .en_i(en), .d_i(pl_hit1_q), .q_o(pl_hit2)
  );
  q_t px_q, pz_q;
  logic pl_hit3_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      px_q <= qadd(EyeX, qx);
      pz_q <= qadd(EyeZ, qz);
      pl_hit3_q <= pl_hit2;
    end
  end
  q_t pl_x, pl_z;
  logic pl_hit;
  pipe_delay #(.WIDTH(2 * WordBits + 1), .DEPTH(AlignLat - PlnLat)) u_pl_align (
    .clk_i, .en_i(en), .d_i({px_q, pz_q, pl_hit3_q}), .q_o({pl_x, pl_z, pl_hit})
  );

  // ---- Merge ---------------------------------------------------------------
  coord_t x_a;
  vec3_t n_a;
  pipe_delay #(.WIDTH($bits(coord_t) + $bits(vec3_t)), .DEPTH(AlignLat)) u_side (
    .clk_i, .en_i(en), .d_i({in_i.x, in_i.n}), .q_o({x_a, n_a})
  );

  always_ff @(posedge clk_i) begin
    if (en) begin
      out_o.x <= x_a;
      out_o.n <= n_a;
      out_o.normal <= sph_normal;
      out_o.sky <= lerp_rgb(SkyHorizon, SkyZenith, clamp_unit(n_a.y));
      if (sph_hit) begin
        out_o.kind <= HitSphere;
        out_o.p <= sph_p;
      end else begin
        out_o.kind <= pl_hit ? HitPlane : HitSky;
        out_o.p <= '{x: pl_x, y: '0, z: pl_z};
      end
    end
  end
endmodule
