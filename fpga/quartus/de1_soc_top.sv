// DE1-SoC top level: the Platform Designer system soc_system (HPS + the
// ray-tracer accelerator on the lightweight HPS-to-FPGA bridge) with its
// HPS DDR3 and HPS peripheral pins (Ethernet EMAC1 RGMII, SD card, UART0)
// and the 50 MHz fabric clock. LEDR[0] lights while the HPS holds the
// fabric out of reset (a cheap sign of life on the board).
module de1_soc_top (
  input  logic        CLOCK_50,
  output logic [0:0]  LEDR,
  // HPS DDR3 (1 GiB, 32-bit)
  output logic [14:0] HPS_DDR3_ADDR,
  output logic [2:0]  HPS_DDR3_BA,
  output logic        HPS_DDR3_CAS_N,
  output logic        HPS_DDR3_CKE,
  output logic        HPS_DDR3_CK_N,
  output logic        HPS_DDR3_CK_P,
  output logic        HPS_DDR3_CS_N,
  output logic [3:0]  HPS_DDR3_DM,
  inout  wire  [31:0] HPS_DDR3_DQ,
  inout  wire  [3:0]  HPS_DDR3_DQS_N,
  inout  wire  [3:0]  HPS_DDR3_DQS_P,
  output logic        HPS_DDR3_ODT,
  output logic        HPS_DDR3_RAS_N,
  output logic        HPS_DDR3_RESET_N,
  input  logic        HPS_DDR3_RZQ,
  output logic        HPS_DDR3_WE_N,
  // HPS Ethernet (EMAC1, RGMII to the KSZ9021RN)
  output logic        HPS_ENET_GTX_CLK,
  output logic        HPS_ENET_MDC,
  inout  wire         HPS_ENET_MDIO,
  input  logic        HPS_ENET_RX_CLK,
  input  logic [3:0]  HPS_ENET_RX_DATA,
  input  logic        HPS_ENET_RX_DV,
  output logic [3:0]  HPS_ENET_TX_DATA,
  output logic        HPS_ENET_TX_EN,
  // HPS SD card
  output logic        HPS_SD_CLK,
  inout  wire         HPS_SD_CMD,
  inout  wire  [3:0]  HPS_SD_DATA,
  // HPS UART0 (USB-UART)
  input  logic        HPS_UART_RX,
  output logic        HPS_UART_TX
);
  logic h2f_rst_n;

  soc_system u_soc (
    .clk_clk                         (CLOCK_50),
    .reset_reset_n                   (1'b1),
    .hps_0_h2f_reset_reset_n         (h2f_rst_n),
    .memory_mem_a                    (HPS_DDR3_ADDR),
    .memory_mem_ba                   (HPS_DDR3_BA),
    .memory_mem_ck                   (HPS_DDR3_CK_P),
    .memory_mem_ck_n                 (HPS_DDR3_CK_N),
    .memory_mem_cke                  (HPS_DDR3_CKE),
    .memory_mem_cs_n                 (HPS_DDR3_CS_N),
    .memory_mem_ras_n                (HPS_DDR3_RAS_N),
    .memory_mem_cas_n                (HPS_DDR3_CAS_N),
    .memory_mem_we_n                 (HPS_DDR3_WE_N),
    .memory_mem_reset_n              (HPS_DDR3_RESET_N),
    .memory_mem_dq                   (HPS_DDR3_DQ),
    .memory_mem_dqs                  (HPS_DDR3_DQS_P),
    .memory_mem_dqs_n                (HPS_DDR3_DQS_N),
    .memory_mem_odt                  (HPS_DDR3_ODT),
    .memory_mem_dm                   (HPS_DDR3_DM),
    .memory_oct_rzqin                (HPS_DDR3_RZQ),
    .hps_io_hps_io_emac1_inst_TX_CLK (HPS_ENET_GTX_CLK),
    .hps_io_hps_io_emac1_inst_TXD0   (HPS_ENET_TX_DATA[0]),
    .hps_io_hps_io_emac1_inst_TXD1   (HPS_ENET_TX_DATA[1]),
    .hps_io_hps_io_emac1_inst_TXD2   (HPS_ENET_TX_DATA[2]),
    .hps_io_hps_io_emac1_inst_TXD3   (HPS_ENET_TX_DATA[3]),
    .hps_io_hps_io_emac1_inst_RXD0   (HPS_ENET_RX_DATA[0]),
    .hps_io_hps_io_emac1_inst_MDIO   (HPS_ENET_MDIO),
    .hps_io_hps_io_emac1_inst_MDC    (HPS_ENET_MDC),
    .hps_io_hps_io_emac1_inst_RX_CTL (HPS_ENET_RX_DV),
    .hps_io_hps_io_emac1_inst_TX_CTL (HPS_ENET_TX_EN),
    .hps_io_hps_io_emac1_inst_RX_CLK (HPS_ENET_RX_CLK),
    .hps_io_hps_io_emac1_inst_RXD1   (HPS_ENET_RX_DATA[1]),
    .hps_io_hps_io_emac1_inst_RXD2   (HPS_ENET_RX_DATA[2]),
    .hps_io_hps_io_emac1_inst_RXD3   (HPS_ENET_RX_DATA[3]),
    .hps_io_hps_io_sdio_inst_CMD     (HPS_SD_CMD),
    .hps_io_hps_io_sdio_inst_D0      (HPS_SD_DATA[0]),
    .hps_io_hps_io_sdio_inst_D1      (HPS_SD_DATA[1]),
    .hps_io_hps_io_sdio_inst_CLK     (HPS_SD_CLK),
    .hps_io_hps_io_sdio_inst_D2      (HPS_SD_DATA[2]),
    .hps_io_hps_io_sdio_inst_D3      (HPS_SD_DATA[3]),
    .hps_io_hps_io_uart0_inst_RX     (HPS_UART_RX),
    .hps_io_hps_io_uart0_inst_TX     (HPS_UART_TX)
  );

  assign LEDR[0] = h2f_rst_n;
endmodule
