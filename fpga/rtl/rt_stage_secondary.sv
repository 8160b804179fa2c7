// Stage 4, shadow-or-reflect (trace.rs shade_sphere / shade_plane / shadowed):
// both secondary rays are traced in parallel and the primary hit picks one.
//   sphere: hit_plane(p, r) gives checker(qx, qz), else sky(r.y);
//           colour = lerp(local, mirrored, REFLECTANCE).
//   plane:  hit_sphere(p, L) nearer than the light (t < |light - p|) shadows;
//           colour = shade(checker(px, pz), lit ? intensity(L.y) : AMBIENT).
//   sky:    the sky colour of the primary ray.
module rt_stage_secondary
  import rt_pkg::*;
#(
  parameter int unsigned SQRT_BPS = 2,
  parameter int unsigned DIV_BPS  = 2
) (
  input  logic    clk_i,
  input  logic    rst_ni,
  input  logic    in_valid_i,
  output logic    in_ready_o,
  input  shade_t  in_i,
  output logic    out_valid_o,
  input  logic    out_ready_i,
  output px_out_t out_o
);
  localparam int SqrtLat = fp_sqrt_lat(SQRT_BPS);
  localparam int DivLat = fp_div_lat(DIV_BPS);
  localparam int MirLat = FpMulLat + DivLat + 3;
  localparam int ShdLat = 4 + CrossLat + DotLat + SqrtLat;
  localparam int AlignLat = (MirLat > ShdLat) ? MirLat : ShdLat;
  localparam int Lat = AlignLat + 1;

  logic en;
  stage_ctrl #(.LAT(Lat)) u_ctrl (
    .clk_i, .rst_ni, .in_valid_i, .in_ready_o, .out_valid_o, .out_ready_i, .en_o(en)
  );

  // ---- Sphere: mirror ray against the plane (hit_plane(p, r)) -----------
  q_t mx, mz;
  fp_mul u_mx (.clk_i, .en_i(en), .a_i(in_i.p.y), .b_i(in_i.r.x), .y_o(mx));
  fp_mul u_mz (.clk_i, .en_i(en), .a_i(in_i.p.y), .b_i(in_i.r.z), .y_o(mz));
  q_t down;
  pipe_delay #(.WIDTH(WordBits), .DEPTH(FpMulLat)) u_down (
    .clk_i, .en_i(en), .d_i(qneg(in_i.r.y)), .q_o(down)
  );
  q_t qx, qz;
  fp_div #(.BPS(DIV_BPS)) u_divx (.clk_i, .en_i(en), .a_i(mx), .b_i(down), .y_o(qx));
  fp_div #(.BPS(DIV_BPS)) u_divz (.clk_i, .en_i(en), .a_i(mz), .b_i(down), .y_o(qz));
  q_t mp_x, mp_z, ry_m;
  pipe_delay #(.WIDTH(3 * WordBits), .DEPTH(FpMulLat + DivLat)) u_mp (
    .clk_i, .en_i(en), .d_i({in_i.p.x, in_i.p.z, in_i.r.y}), .q_o({mp_x, mp_z, ry_m})
  );
  q_t hx_q, hz_q, ry_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      hx_q <= qadd(mp_x, qx);
      hz_q <= qadd(mp_z, qz);
      ry_q <= ry_m;
    end
  end
  rgb_t mirrored_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      mirrored_q <= (ry_q < 0) ? checker_rgb(hx_q, hz_q)
                               : lerp_rgb(SkyHorizon, SkyZenith, clamp_unit(ry_q));
    end
  end
  rgb_t local_m;
  pipe_delay #(.WIDTH($bits(rgb_t)), .DEPTH(MirLat - 1)) u_local (
    .clk_i, .en_i(en), .d_i(in_i.local_rgb), .q_o(local_m)
  );
  rgb_t sph_col_q;
  always_ff @(posedge clk_i) begin
    if (en) sph_col_q <= lerp_rgb(local_m, mirrored_q, clamp_unit(Reflectance));
  end

  // ---- Plane: shadow ray against the sphere (hit_sphere(p, L)) ---------
  // oc = SPHERE_CENTRE - p with p = (px, 0, pz).
  vec3_t oc_q, ldir1_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      oc_q.x <= qneg(in_i.p.x);
      oc_q.y <= CentreY;
      oc_q.z <= qneg(in_i.p.z);
      ldir1_q <= in_i.ldir;
    end
  end
  q_t sb;
  vec3_t perp;
  vec3_dot u_b (.clk_i, .en_i(en), .a_i(oc_q), .b_i(ldir1_q), .y_o(sb));
  vec3_cross u_perp (.clk_i, .en_i(en), .a_i(oc_q), .b_i(ldir1_q), .y_o(perp));
  // Elaboration check for simulation and lint only (Quartus never sees it).
  // synthesis translate_off
  generate
  if (CrossLat != DotLat) begin : g_cross_check
    $error("b and oc x L must arrive together");
  end
  endgenerate
  // synthesis translate_on
  q_t d2, sb3;
  vec3_dot u_d2 (.clk_i, .en_i(en), .a_i(perp), .b_i(perp), .y_o(d2));
  pipe_delay #(.WIDTH(WordBits), .DEPTH(DotLat)) u_sb3 (
    .clk_i, .en_i(en), .d_i(sb), .q_o(sb3)
  );
  q_t rad_q, sb4_q;
  logic shit4_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      shit4_q <= (sb3 > 0) && (d2 <= QOne);
      rad_q   <= qsub(QOne, d2);
      sb4_q   <= sb3;
    end
  end
  q_t sq, sb5;
  logic shit5;
  fp_sqrt #(.BPS(SQRT_BPS)) u_sqrt (.clk_i, .en_i(en), .a_i(rad_q), .y_o(sq));
  pipe_delay #(.WIDTH(WordBits + 1), .DEPTH(SqrtLat)) u_sb5 (
    .clk_i, .en_i(en), .d_i({sb4_q, shit4_q}), .q_o({sb5, shit5})
  );
  q_t st_q;
  logic shit6_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      st_q <= qsub(sb5, sq);
      shit6_q <= shit5;
    end
  end
  q_t llen_s, spx, spz;
  logic [10:0] plane_i_s;
  logic cpos_s;
  pipe_delay #(.WIDTH(3 * WordBits + 12), .DEPTH(ShdLat - 1)) u_pl (
    .clk_i, .en_i(en),
    .d_i({in_i.llen, in_i.p.x, in_i.p.z, in_i.plane_i, in_i.plane_cpos}),
    .q_o({llen_s, spx, spz, plane_i_s, cpos_s})
  );
  rgb_t pl_col_q;
  always_ff @(posedge clk_i) begin
    if (en) begin
      pl_col_q <= shade_rgb(checker_rgb(spx, spz),
                            (cpos_s && !(shit6_q && st_q < llen_s)) ? plane_i_s
                                                                   : Ambient[10:0]);
    end
  end

  // ---- Merge ---------------------------------------------------------------
  rgb_t sph_col, pl_col;
  pipe_delay #(.WIDTH($bits(rgb_t)), .DEPTH(AlignLat - MirLat)) u_sph_al (
    .clk_i, .en_i(en), .d_i(sph_col_q), .q_o(sph_col)
  );
  pipe_delay #(.WIDTH($bits(rgb_t)), .DEPTH(AlignLat - ShdLat)) u_pl_al (
    .clk_i, .en_i(en), .d_i(pl_col_q), .q_o(pl_col)
  );
  coord_t x_a;
  hit_e kind_a;
  rgb_t sky_a;
  pipe_delay #(.WIDTH($bits(coord_t) + $bits(hit_e) + $bits(rgb_t)), .DEPTH(AlignLat)) u_side (
    .clk_i, .en_i(en), .d_i({in_i.x, in_i.kind, in_i.sky}), .q_o({x_a, kind_a, sky_a})
  );
  always_ff @(posedge clk_i) begin
    if (en) begin
      out_o.x <= x_a;
      unique case (kind_a)
        HitSphere: out_o.rgb <= sph_col;
        HitPlane:  out_o.rgb <= pl_col;
        default:   out_o.rgb <= sky_a;
      endcase
    end
  end
endmodule
