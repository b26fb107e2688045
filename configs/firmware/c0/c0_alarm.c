/*
 * c0_alarm.c: the alarm module C0 (suction doors and duct vacuum) as AT89C51CC03 firmware.
 *
 * It behaves as the script node configs/nodes/c0.ron: from 60 ms after reset it looks at its
 * inputs every 10 ms and sends the frame alarm.suction_doors (docs/PROTOCOL.md) when the
 * frame's content differs from the last one sent, or when 1000 ms have passed since that
 * send. The heartbeat restarts with every frame sent, whatever made it go.
 *
 * Hardware, as the firmware node file wires it:
 *   - 12 MHz crystal, X1 mode: a machine cycle is 1 us; F_CAN = 6 MHz.
 *   - Door switches of rows 1-6 on P2.0-P2.5, pin high = door open.
 *   - Duct vacuum sensor on ADC channel 0 (P1.0), VAREF = 5000 mV; the pin's voltage in mV is
 *     the signal.
 *   - CAN at 250 kbit/s on the on-chip controller (TxDC/RxDC).
 *
 * Frame: extended identifier 0400F5C0 (priority 4, broadcast, C0 to the monitor F5), DLC 4:
 * Data0 = 30h, Data1 bits 0-5 = doors 1-6, Data2-3 = duct vacuum in mV, little-endian,
 * quantized to 100 mV.
 *
 * Build (in this folder; the HEX is configs/firmware/c0_alarm.hex, its debug files beside it):
 *   sdcc -mmcs51 --model-small --debug -o c0_alarm.ihx c0_alarm.c && cp c0_alarm.ihx c0_alarm.cdb ..
 *   packihx c0_alarm.ihx > ../c0_alarm.hex
 */
#include "at89c51cc03.h"

/* Timer 2 counts machine cycles (1 us): 10 000 counts are 10 ms. */
#define TICK_RELOAD (65536u - 10000u)
/* Machine cycles from reset until timer 2 counts its first cycle (the reset jump, the start
 * code's stack set-up and call, and the writes below), so that tick n falls at n x 10 ms. */
#define CYCLES_BEFORE_RUN 16u

#define BOOT_TICKS 6        /* boot_delay_ms 60 */
#define HEARTBEAT_TICKS 100 /* heartbeat_ms 1000 */

#define DOOR_MASK 0x3F
#define MESSAGE_SUCTION_DOORS 0x30

#define RX_CHANNEL 0
#define TX_CHANNEL 1
#define CHANNELS 15

/* Ticks of 10 ms since reset, counted by the timer 2 interrupt. */
volatile unsigned char ticks;
/* Times the CAN controller was restarted after bus-off. */
unsigned int can_restarts;

/* The content of the last frame sent. */
static unsigned char sent_doors;
static unsigned int sent_vacuum;
static __bit sent_any;
/* Ticks since the last frame was sent. */
static unsigned char since_sent;
/* A frame is decided but not yet handed to the controller (the last one is still on its way). */
static __bit send_pending;
/* Channel TX_CHANNEL holds a frame the controller has not reported sent. */
static __bit tx_busy;

/* Starts timer 2 before the C start-up code clears RAM, so that ticks count from reset. */
unsigned char _sdcc_external_startup(void)
{
    RCAP2L = TICK_RELOAD & 0xFF;
    RCAP2H = TICK_RELOAD >> 8;
    TL2 = (TICK_RELOAD + CYCLES_BEFORE_RUN) & 0xFF;
    TH2 = (TICK_RELOAD + CYCLES_BEFORE_RUN) >> 8;
    T2CON = T2CON_TR2;
    return 0;
}

void timer2_isr(void) __interrupt(5)
{
    TF2 = 0;
    ticks++;
}

/* The whole CAN set-up, after a general reset: used at start and after bus-off. */
static void can_setup(void)
{
    unsigned char c;

    CANGCON = CANGCON_GRES;
    /* Message objects keep their contents over a general reset and have no reset value:
     * disable all of them. */
    for (c = 0; c < CHANNELS; c++) {
        CANPAGE = CANPAGE_CHANNEL(c);
        CANSTCH = 0;
        CANCONCH = CANCONCH_DISABLE;
    }
    /* 250 kbit/s from F_CAN = 6 MHz: BRP = 1 (a quantum is 1/3 us), PRS = 2, PHS1 = 3,
     * PHS2 = 3, SJW = 0: 1 + 3 + 4 + 4 = 12 quanta = 4 us a bit. */
    CANBT1 = 0x02;
    CANBT2 = 0x04;
    CANBT3 = 0x36;

    /* Channel 0 receives what the monitor would address to C0 (0400C0F5), nothing else:
     * CANIDT = identifier << 3, every identifier bit, RTR and IDE compared. */
    CANPAGE = CANPAGE_CHANNEL(RX_CHANNEL);
    CANIDT1 = 0x20;
    CANIDT2 = 0x06;
    CANIDT3 = 0x07;
    CANIDT4 = 0xA8;
    CANIDM1 = 0xFF;
    CANIDM2 = 0xFF;
    CANIDM3 = 0xFF;
    CANIDM4 = 0xFD;
    CANCONCH = CANCONCH_RX | CANCONCH_IDE | 8;

    /* Channel 1 sends: identifier 0400F5C0 << 3, a data frame (RTRTAG 0). */
    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL);
    CANIDT1 = 0x20;
    CANIDT2 = 0x07;
    CANIDT3 = 0xAE;
    CANIDT4 = 0x00;

    tx_busy = 0;
    CANGCON = CANGCON_ENA;
}

/* One conversion of ADC channel 0, as a 10-bit code. */
static unsigned int adc_read(void)
{
    ADCON = ADCON_ADEN | ADCON_ADSST | 0;
    while (!(ADCON & ADCON_ADEOC))
        ;
    ADCON = ADCON_ADEN;
    return ((unsigned int)ADDH << 2) | (ADDL & 0x03);
}

/* The code as mV at the centre of its bin, (code + 1/2) x 5000 / 1024, rounded to the nearest
 * 100 mV. (2 code + 1) x 25 / 1024 is that value in hundreds of mV; it never ends in exactly
 * one half (the numerator is odd), so adding 512 before the division rounds it. */
static unsigned int vacuum_mv(unsigned int code)
{
    unsigned char hundreds = (unsigned char)((((code << 1) + 1) * 25u + 512u) >> 10);
    return (unsigned int)hundreds * 100u;
}

static void send_frame(void)
{
    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL); /* INDX 0, moving on after each byte */
    CANMSG = MESSAGE_SUCTION_DOORS;
    CANMSG = sent_doors;
    CANMSG = sent_vacuum & 0xFF;
    CANMSG = sent_vacuum >> 8;
    CANSTCH = 0;
    CANCONCH = CANCONCH_TX | CANCONCH_IDE | 4;
    tx_busy = 1;
    send_pending = 0;
}

/* What the script does at each check: sample, compare with the last frame sent, send on a
 * change or when the heartbeat is due. */
static void check(void)
{
    unsigned char doors = P2 & DOOR_MASK;
    unsigned int vacuum = vacuum_mv(adc_read());

    if (since_sent < HEARTBEAT_TICKS)
        since_sent++;
    if (!sent_any || doors != sent_doors || vacuum != sent_vacuum || since_sent >= HEARTBEAT_TICKS) {
        sent_doors = doors;
        sent_vacuum = vacuum;
        sent_any = 1;
        since_sent = 0;
        send_pending = 1;
    }
}

/* Channel housekeeping once a tick: a frame sent frees the transmit channel; a frame received
 * (the node takes none) re-arms the receive channel. */
static void can_service(void)
{
    if (tx_busy) {
        CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL);
        if (CANSTCH & CANSTCH_TXOK) {
            CANSTCH = 0;
            tx_busy = 0;
        }
    }
    CANPAGE = CANPAGE_CHANNEL(RX_CHANNEL);
    if (CANSTCH & CANSTCH_RXOK) {
        CANSTCH = 0;
        CANCONCH = CANCONCH_RX | CANCONCH_IDE | 8;
    }
}

void main(void)
{
    unsigned char seen = 0;
    unsigned char boot = BOOT_TICKS;

    ADCF = 0x01;  /* P1.0 is an analog input */
    ADCLK = 0x03; /* ADC clock 6 MHz / (4 x 3) = 500 kHz */
    ADCON = ADCON_ADEN;
    can_setup();
    ET2 = 1;
    EA = 1;

    for (;;) {
        while (seen == ticks) {
            if (CANGSTA & CANGSTA_BOFF) {
                /* A frame lost with the controller goes out again after the restart. */
                if (tx_busy)
                    send_pending = 1;
                can_setup();
                can_restarts++;
            }
        }
        seen++;
        if (boot) {
            boot--;
            if (boot)
                continue;
        }
        can_service();
        check();
        if (send_pending && !tx_busy)
            send_frame();
    }
}
