/*
 * at89c51cc03.h: special function registers of the Atmel AT89C51CC03 for SDCC (mcs51).
 *
 * Written from the AT89C51CC03 data sheet (Atmel 4182): its SFR mapping table for the
 * addresses and the register tables of the chapters named below for the bits. The core, port,
 * timer, watchdog, interrupt, ADC and CAN registers are here; the PCA, SPI and flash/EEPROM
 * registers are left out. Every address agrees with what the emulator implements (mcs51 core:
 * cc03.rs, adc.rs, timer2.rs, interrupts.rs; CAN controller: bus::at89c51cc::sfr); CKCON1,
 * AUXR1 and P4, which the emulator does not model, are at the addresses the family's public
 * register headers give.
 */
#ifndef AT89C51CC03_H
#define AT89C51CC03_H

/* 80C51 core ("SFR Mapping"). */
__sfr __at(0xE0) ACC;
__sfr __at(0xF0) B;
__sfr __at(0xD0) PSW;
__sfr __at(0x81) SP;
__sfr __at(0x82) DPL;
__sfr __at(0x83) DPH;
__sfr __at(0x87) PCON;
__sfr __at(0x98) SCON;
__sfr __at(0x99) SBUF;

/* I/O ports. P4 has two pins, TxDC (P4.0) and RxDC (P4.1). */
__sfr __at(0x80) P0;
__sfr __at(0x90) P1;
__sfr __at(0xA0) P2;
__sfr __at(0xB0) P3;
__sfr __at(0xC0) P4;

/* Clock, memory ("X2 Feature", "Expanded RAM"). */
__sfr __at(0x8F) CKCON0;
__sfr __at(0x9F) CKCON1;
__sfr __at(0x8E) AUXR;
__sfr __at(0xA2) AUXR1;

/* Timers 0 and 1. */
__sfr __at(0x88) TCON;
__sfr __at(0x89) TMOD;
__sfr __at(0x8A) TL0;
__sfr __at(0x8B) TL1;
__sfr __at(0x8C) TH0;
__sfr __at(0x8D) TH1;

/* Timer 2 ("Timer 2"). */
__sfr __at(0xC8) T2CON;
__sfr __at(0xC9) T2MOD;
__sfr __at(0xCA) RCAP2L;
__sfr __at(0xCB) RCAP2H;
__sfr __at(0xCC) TL2;
__sfr __at(0xCD) TH2;

/* Watchdog ("Hardware Watchdog Timer"). */
__sfr __at(0xA6) WDTRST;
__sfr __at(0xA7) WDTPRG;

/* Interrupts ("Interrupt System"). IEN0 is the 80C51's IE, IPL0 its IP. */
__sfr __at(0xA8) IEN0;
__sfr __at(0xE8) IEN1;
__sfr __at(0xB8) IPL0;
__sfr __at(0xB7) IPH0;
__sfr __at(0xF8) IPL1;
__sfr __at(0xF7) IPH1;

/* Analog-to-digital converter ("Analog-to-Digital Converter"). */
__sfr __at(0xF3) ADCON;
__sfr __at(0xF6) ADCF;
__sfr __at(0xF2) ADCLK;
__sfr __at(0xF5) ADDH;
__sfr __at(0xF4) ADDL;

/* CAN controller ("CAN Controller"). The page registers (CANSTCH, CANCONCH, CANIDT, CANIDM,
 * CANSTMP, CANMSG) show the message object CANPAGE selects. */
__sfr __at(0x9B) CANGIT;
__sfr __at(0x9C) CANTEC;
__sfr __at(0x9D) CANREC;
__sfr __at(0xA1) CANTCON;
__sfr __at(0xA3) CANMSG;
__sfr __at(0xA4) CANTTCL;
__sfr __at(0xA5) CANTTCH;
__sfr __at(0xAA) CANGSTA;
__sfr __at(0xAB) CANGCON;
__sfr __at(0xAC) CANTIML;
__sfr __at(0xAD) CANTIMH;
__sfr __at(0xAE) CANSTMPL;
__sfr __at(0xAF) CANSTMPH;
__sfr __at(0xB1) CANPAGE;
__sfr __at(0xB2) CANSTCH;
__sfr __at(0xB3) CANCONCH;
__sfr __at(0xB4) CANBT1;
__sfr __at(0xB5) CANBT2;
__sfr __at(0xB6) CANBT3;
__sfr __at(0xBA) CANSIT1;
__sfr __at(0xBB) CANSIT2;
__sfr __at(0xBC) CANIDT1;
__sfr __at(0xBD) CANIDT2;
__sfr __at(0xBE) CANIDT3;
__sfr __at(0xBF) CANIDT4;
__sfr __at(0xC1) CANGIE;
__sfr __at(0xC2) CANIE1;
__sfr __at(0xC3) CANIE2;
__sfr __at(0xC4) CANIDM1;
__sfr __at(0xC5) CANIDM2;
__sfr __at(0xC6) CANIDM3;
__sfr __at(0xC7) CANIDM4;
__sfr __at(0xCE) CANEN1;
__sfr __at(0xCF) CANEN2;

/* Bit-addressable registers: the bits used. */
__sbit __at(0x8C) TR0;
__sbit __at(0x8D) TF0;
__sbit __at(0x8E) TR1;
__sbit __at(0x8F) TF1;

__sbit __at(0xA8) EX0;
__sbit __at(0xA9) ET0;
__sbit __at(0xAA) EX1;
__sbit __at(0xAB) ET1;
__sbit __at(0xAC) ES;
__sbit __at(0xAD) ET2;
__sbit __at(0xAE) EC;
__sbit __at(0xAF) EA;

__sbit __at(0xE8) ECAN;
__sbit __at(0xE9) EADC;
__sbit __at(0xEA) ETIM;
__sbit __at(0xEB) ESPI;

__sbit __at(0xC8) CP_RL2;
__sbit __at(0xC9) C_T2;
__sbit __at(0xCA) TR2;
__sbit __at(0xCB) EXEN2;
__sbit __at(0xCC) TCLK;
__sbit __at(0xCD) RCLK;
__sbit __at(0xCE) EXF2;
__sbit __at(0xCF) TF2;

/* CKCON0: X2 (bit 0) halves the machine cycle to 6 oscillator clocks. */
#define CKCON0_X2 0x01

/* T2CON values. */
#define T2CON_TR2 0x04 /* run; CP/RL2 = 0: 16-bit auto-reload from RCAP2 */

/* ADCON. */
#define ADCON_PSIDLE 0x40
#define ADCON_ADEN 0x20  /* converter on */
#define ADCON_ADEOC 0x10 /* end of conversion, cleared by software */
#define ADCON_ADSST 0x08 /* start; cleared by hardware at the end */
#define ADCON_SCH 0x07   /* channel: input P1.SCH */

/* CANGCON. */
#define CANGCON_ABRQ 0x80
#define CANGCON_ENA 0x02
#define CANGCON_GRES 0x01

/* CANGSTA (read only). */
#define CANGSTA_TBSY 0x10
#define CANGSTA_ENFG 0x04
#define CANGSTA_BOFF 0x02
#define CANGSTA_ERRP 0x01

/* CANSTCH. */
#define CANSTCH_TXOK 0x40
#define CANSTCH_RXOK 0x20

/* CANCONCH: CONCH (7:6), IDE (4), DLC (3:0). */
#define CANCONCH_DISABLE 0x00
#define CANCONCH_TX 0x40
#define CANCONCH_RX 0x80
#define CANCONCH_IDE 0x10

/* CANPAGE: CHNB (7:4), AINC (3, 0 = the data index moves on after each CANMSG access), INDX. */
#define CANPAGE_CHANNEL(n) ((unsigned char)((n) << 4))

#endif
