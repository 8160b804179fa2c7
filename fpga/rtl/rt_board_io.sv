// Board I/O (hal-avalon map.rs "Board I/O"): the keys through a two-flop
// synchroniser and a debouncer (a new level must hold DEBOUNCE clocks,
// KEY_DEBOUNCE_CLOCKS), the switches through a two-flop synchroniser, and
// the LED and 7-segment pins from the registers (HEX segments active low
// on the pins, 1 = lit in the registers).
module rt_board_io #(
  parameter int unsigned DEBOUNCE = 1 << 20  // hal-avalon KEY_DEBOUNCE_CLOCKS
) (
  input  logic        clk_i,
  input  logic        rst_ni,
  input  logic [3:0]  key_n_i,       // pins, active low
  input  logic [9:0]  sw_i,
  output logic [3:0]  keys_down_o,   // debounced, 1 = pressed
  output logic [3:0]  keys_went_o,   // pulse: the key went down
  output logic [9:0]  switches_o,
  input  logic [9:0]  leds_i,
  input  logic [31:0] hex_lo_i,
  input  logic [15:0] hex_hi_i,
  output logic [9:0]  ledr_o,
  output logic [6:0]  hex0_n_o,
  output logic [6:0]  hex1_n_o,
  output logic [6:0]  hex2_n_o,
  output logic [6:0]  hex3_n_o,
  output logic [6:0]  hex4_n_o,
  output logic [6:0]  hex5_n_o
);
  localparam int unsigned CntW = $clog2(DEBOUNCE);

  logic [3:0] key_meta_q, key_sync_q, down_q, went_q;
  logic [9:0] sw_meta_q, sw_sync_q;
  logic [CntW-1:0] cnt_q [4];

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin : p_keys_reset
      key_meta_q <= '0;
      key_sync_q <= '0;
      down_q     <= '0;
      went_q     <= '0;
      sw_meta_q  <= '0;
      sw_sync_q  <= '0;
      for (int k = 0; k < 4; k++) cnt_q[k] <= '0;
    end else begin : p_keys
      key_meta_q <= ~key_n_i;
      key_sync_q <= key_meta_q;
      sw_meta_q <= sw_i;
      sw_sync_q <= sw_meta_q;
      went_q <= '0;
      for (int k = 0; k < 4; k++) begin
        if (key_sync_q[k] == down_q[k]) begin
          cnt_q[k] <= '0;
        end else if (cnt_q[k] == CntW'(DEBOUNCE - 1)) begin
          cnt_q[k] <= '0;
          down_q[k] <= key_sync_q[k];
          went_q[k] <= key_sync_q[k];
        end else begin
          cnt_q[k] <= cnt_q[k] + CntW'(1);
        end
      end
    end
  end
  assign keys_down_o = down_q;
  assign keys_went_o = went_q;
  assign switches_o = sw_sync_q;

  assign ledr_o = leds_i;
  assign hex0_n_o = ~hex_lo_i[6:0];
  assign hex1_n_o = ~hex_lo_i[14:8];
  assign hex2_n_o = ~hex_lo_i[22:16];
  assign hex3_n_o = ~hex_lo_i[30:24];
  assign hex4_n_o = ~hex_hi_i[6:0];
  assign hex5_n_o = ~hex_hi_i[14:8];

  /* verilator lint_off UNUSEDSIGNAL */
  logic unused_hex;
  assign unused_hex = ^{hex_lo_i[31], hex_lo_i[23], hex_lo_i[15], hex_lo_i[7], hex_hi_i[15], hex_hi_i[7]};
  /* verilator lint_on UNUSEDSIGNAL */
endmodule
