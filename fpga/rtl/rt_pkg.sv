// Shared types, scene constants and primitive latencies of the ray tracer.
//
// Every number format and constant mirrors the Rust model, which is the
// specification: model/src/word.rs (Q13.10 word), model/src/scene.rs (scene),
// model/src/arith.rs (primitives). Latency functions live here so a parent can
// align side data with a parameterised primitive without reading its body.
package rt_pkg;

  // ---- Q13.10 word (model/src/word.rs) ------------------------------------
  localparam int unsigned WordBits = 24;  // WORD_BITS
  localparam int unsigned FracBits = 10;  // FRAC_BITS
  typedef logic signed [WordBits-1:0] q_t;
  localparam q_t QMax = 24'sh7fffff;  // RAW_MAX
  localparam q_t QMin = 24'sh800000;  // RAW_MIN
  localparam q_t QOne = 24'sd1024;    // Q::ONE

  typedef struct packed {
    q_t x;
    q_t y;
    q_t z;
  } vec3_t;

  // 25-bit exact difference of two words (model WideVec3::sub).
  typedef logic signed [WordBits:0] wide_t;
  typedef struct packed {
    wide_t x;
    wide_t y;
    wide_t z;
  } wvec3_t;

  typedef struct packed {
    logic [7:0] r;
    logic [7:0] g;
    logic [7:0] b;
  } rgb_t;

  // ---- Scene (model/src/scene.rs) -----------------------------------------
  localparam int unsigned Width  = 480;  // WIDTH
  localparam int unsigned Height = 360;  // HEIGHT
  localparam int CamRightX = 61;         // CAMERA_RIGHT_X
  localparam int CamUpY = 60;            // CAMERA_UP.0
  localparam int CamUpZ = 11;            // CAMERA_UP.1
  localparam int CamFwdY = -11;          // CAMERA_FORWARD.0
  localparam int CamFwdZ = 60;           // CAMERA_FORWARD.1
  localparam int FocalHalfPixels = 800;  // FOCAL_HALF_PIXELS
  localparam q_t EyeX = 24'sd0;          // EYE = (0, 2, -6)
  localparam q_t EyeY = 24'sd2048;
  localparam q_t EyeZ = -24'sd6144;
  localparam q_t CentreY = 24'sd1024;    // SPHERE_CENTRE = (0, 1, 0)
  localparam q_t Ambient = 24'sd256;     // AMBIENT (0.25)
  localparam q_t Reflectance = 24'sd384; // REFLECTANCE (0.375)
  localparam rgb_t SkyHorizon  = '{r: 8'd200, g: 8'd222, b: 8'd250};  // SKY_HORIZON
  localparam rgb_t SkyZenith   = '{r: 8'd40,  g: 8'd90,  b: 8'd190};  // SKY_ZENITH
  localparam rgb_t CheckerEven = '{r: 8'd230, g: 8'd230, b: 8'd230};  // CHECKER_EVEN
  localparam rgb_t CheckerOdd  = '{r: 8'd200, g: 8'd30,  b: 8'd30};   // CHECKER_ODD
  localparam rgb_t SphereBase  = '{r: 8'd30,  g: 8'd70,  b: 8'd230};  // SPHERE_BASE

  // ---- Stage payloads ------------------------------------------------------
  typedef logic [8:0] coord_t;  // 9-bit pixel coordinate (trace.rs COORD_MASK)

  typedef enum logic [1:0] {
    HitSky    = 2'd0,
    HitPlane  = 2'd1,
    HitSphere = 2'd2
  } hit_e;

  // Scheduler -> compute-ray.
  typedef struct packed {
    coord_t x;
    coord_t y;
  } pix_t;

  // compute-ray -> intersect: exact camera ray d and its normalised form n.
  typedef struct packed {
    coord_t x;
    vec3_t  d;
    vec3_t  n;
  } ray_t;

  // intersect -> shade: what the primary ray hit. p is the sphere point or
  // the plane point (px, 0, pz); normal is p - SPHERE_CENTRE (sphere only).
  typedef struct packed {
    coord_t x;
    hit_e   kind;
    vec3_t  p;
    vec3_t  normal;
    vec3_t  n;
    rgb_t   sky;
  } isect_t;

  // shade -> shadow-or-reflect: the light direction and distance, the sphere's
  // local colour and mirror ray, the plane's lit intensity.
  typedef struct packed {
    coord_t     x;
    hit_e       kind;
    vec3_t      p;
    vec3_t      ldir;
    q_t         llen;
    rgb_t       local_rgb;  // sphere: shade(SPHERE_BASE, intensity(N . L))
    vec3_t      r;          // sphere: mirror ray n - 2 (n . N) N
    logic [10:0] plane_i;   // plane: intensity(L.y)
    logic       plane_cpos; // plane: L.y > 0
    rgb_t       sky;
  } shade_t;

  // Lane output: one finished pixel.
  typedef struct packed {
    coord_t x;
    rgb_t   rgb;
  } px_out_t;

  // ---- Register map (hal-avalon src/map.rs) --------------------------------
  // Version 3: version 2's row and frame DMA registers plus the VGA
  // scan-out and the board I/O block.
  localparam logic [31:0] IdValue = 32'h5254_0003;

  // ---- Frame DMA (hal-avalon src/map.rs, docs/frame-dma.md) -----------------
  localparam int unsigned RowBytes   = Width * 3;     // 1440: RGB888 wire row
  localparam int unsigned RowBeats   = RowBytes / 8;  // 180 64-bit beats
  localparam int unsigned BurstBeats = 16;            // AXI3 INCR maximum
  typedef logic [8:0] row_t;                          // 0..360
  // Line-buffer slots per bank: row r of a frame goes to slot r % 4, so the
  // lanes render rows r+1..r+3 while the DMA packs row r (with two slots
  // the lanes would wait for the packer every other row).
  localparam int unsigned LbSlots = 4;
  localparam int unsigned SlotW = $clog2(LbSlots);
  typedef logic [SlotW-1:0] slot_t;

  // ---- Saturation (Q::saturate) -------------------------------------------
  // Clamp a wide signed value to the word range; callers sign-extend into 64.
  function automatic q_t qsat(input logic signed [63:0] v);
    if (v > 64'sd8388607) return QMax;
    if (v < -64'sd8388608) return QMin;
    return v[WordBits-1:0];
  endfunction

  // round_wide: sat((p + 2^9) >>> 10) of a full-width product or sum.
  function automatic q_t qround(input logic signed [63:0] p);
    logic signed [63:0] r;
    r = (p + 64'sd512) >>> FracBits;
    return qsat(r);
  endfunction

  function automatic logic signed [63:0] qext(input q_t a);
    return 64'(a);
  endfunction

  // fp_add / fp_sub / fp_neg
  function automatic q_t qadd(input q_t a, input q_t b);
    return qsat(qext(a) + qext(b));
  endfunction
  function automatic q_t qsub(input q_t a, input q_t b);
    return qsat(qext(a) - qext(b));
  endfunction
  function automatic q_t qneg(input q_t a);
    return qsat(-qext(a));
  endfunction

  // clamp_unit: [0, 1.0] as an 11-bit factor.
  function automatic logic [10:0] clamp_unit(input q_t a);
    if (a < 0) return 11'd0;
    if (a > QOne) return 11'd1024;
    return a[10:0];
  endfunction

  // colour.rs lerp_channel: a + (((b - a) * t + 2^9) >> 10), kept to 8 bits.
  // (b - a) is 9 bits signed, t 12 bits with its zero sign bit: the signed
  // product and the rounding constant fit the 22-bit target.
  function automatic logic [7:0] lerp_ch(input logic [7:0] a, input logic [7:0] b,
                                         input logic [10:0] t);
    logic signed [8:0] diff;
    logic signed [21:0] p;
    diff = $signed({1'b0, b}) - $signed({1'b0, a});
    p = diff * $signed({1'b0, t}) + 22'sd512;
    return a + 8'(p >>> FracBits);
  endfunction

  // colour.rs scale_channel: (a * t + 2^9) >> 10, t <= 1.0.
  function automatic logic [7:0] scale_ch(input logic [7:0] a, input logic [10:0] t);
    logic [19:0] p;
    p = a * t + 20'd512;  // 8 x 11 bits unsigned into the 20-bit target
    return 8'(p >> FracBits);
  endfunction

  function automatic rgb_t lerp_rgb(input rgb_t a, input rgb_t b, input logic [10:0] t);
    return '{r: lerp_ch(a.r, b.r, t), g: lerp_ch(a.g, b.g, t), b: lerp_ch(a.b, b.b, t)};
  endfunction

  function automatic rgb_t shade_rgb(input rgb_t a, input logic [10:0] t);
    return '{r: scale_ch(a.r, t), g: scale_ch(a.g, t), b: scale_ch(a.b, t)};
  endfunction

  // trace.rs intensity: AMBIENT + fp_mul(1 - AMBIENT, clamp_unit(cos)), <= 1.0.
  function automatic logic [10:0] intensity(input q_t cosine);
    logic [20:0] p;
    p = 10'd768 * clamp_unit(cosine) + 21'd512;  // 10 x 11 bits into 21
    return 11'd256 + 11'(p >> FracBits);
  endfunction

  // trace.rs checker: bit 10 of x ^ z selects the odd colour.
  function automatic rgb_t checker_rgb(input q_t x, input q_t z);
    return (x[FracBits] ^ z[FracBits]) ? CheckerOdd : CheckerEven;
  endfunction

  // ---- Primitive latencies (clock cycles, input to registered output) -----
  function automatic int ceil_div(input int a, input int b);
    return (a + b - 1) / b;
  endfunction
  localparam int FpMulLat = 2;  // product register, round/saturate register
  localparam int DotLat = 2;    // products, sum + round
  localparam int CrossLat = 2;
  function automatic int udiv_lat(input int q_w, input int bps);
    return ceil_div(q_w, bps);
  endfunction
  function automatic int isqrt_lat(input int r_w, input int bps);
    return ceil_div(r_w, bps);
  endfunction
  // input register (magnitudes, overflow), 24 quotient bits, sign/saturate
  function automatic int fp_div_lat(input int bps);
    return 2 + udiv_lat(WordBits, bps);
  endfunction
  // radicand register, 17 root bits of a 34-bit radicand
  function automatic int fp_sqrt_lat(input int bps);
    return 1 + isqrt_lat(17, bps);
  endfunction
  // abs/max, shift, squares, sum; 15-bit isqrt; 21-bit reciprocal; mul; round
  function automatic int normalize_lat(input int sqrt_bps, input int div_bps);
    return 4 + isqrt_lat(15, sqrt_bps) + udiv_lat(21, div_bps) + 2;
  endfunction

endpackage
