/*
 * flow_sensor.c: the near-infrared cotton flow sensor (D0-D5) as AT89C51CC03 firmware.
 *
 * One image serves all six sensors: what differs from one to the next (its address, its CAN
 * identifiers, its boot delay, the phase of its groups, which ADC channel reads which unit) is
 * in a configuration block at FF00h in code memory that the node file supplies (below). The
 * image itself writes nothing at FF00h or above.
 *
 * It behaves as the script template configs/nodes/templates/flow_sensor.ron:
 *   - after its boot delay it is "awaiting calibration" and reports flow.status (state,
 *     firmware 3, missed_acks) when a check every 20 ms finds it changed, and at least every
 *     250 ms;
 *   - flow.calibrate from the monitor: command 1 (start calibration) drives the emitters to the
 *     target reference the command carries (the DAC on P0/P2), answers every group sent so
 *     far and enters "calibrating"; command 2 (accept and run) answers every group sent so far
 *     and enters "running"; command 0 (stop) enters "awaiting calibration";
 *   - the reference group (marker 20 0E, part1 with units 1-3, part2 with units 4-5 and aux
 *     7263300) every 100 ms while calibrating or running, the flow group (marker 20 0D, part1
 *     with status 1, part2 with aux 16739984) every 100 ms while running, flow first, both at
 *     the node's phase on a 100 ms grid from the end of boot;
 *   - every group awaits the monitor's flow.ack; any flow.ack answers every group before it.
 *     A group whose acknowledgement has not come 50 ms after it is missed (missed_acks);
 *     three in a row and the sensor enters "no acknowledgement" (state 4) and stops
 *     streaming; the next flow.ack, or "accept and run", takes it back to the state it gave up
 *     in, and it streams again on the same grid.
 *
 * Hardware, as the node file wires it:
 *   - 12 MHz crystal, X1 mode: a machine cycle is 1 us; F_CAN = 6 MHz.
 *   - CAN at 250 kbit/s on the on-chip controller.
 *   - The five detection units on ADC channels (P1.x, VAREF 5000 mV), one channel per unit
 *     (the configuration block says which). In front of each channel an analog multiplexer
 *     passes the unit's calibrated reference level instead of its value while its select line
 *     is high. The select lines are port pins of P1 and P3 that the configuration block names
 *     by two masks; the firmware drives them all together (high for the references, low for
 *     the values). The board has one select line for all five multiplexers, P3.4: a mask with
 *     one bit.
 *     The units' values are scaled 64 counts per ADC step (0-65535 counts over 0-5000 mV),
 *     the references 16 counts per step (0-16383 counts), each with half a step of offset, so
 *     that code c is the bin centred on c x 64 (c x 16) counts: the firmware sends code << 6
 *     (code << 4), and an empty duct (0 counts) reads 0.
 *   - The target reference level drives a 16-bit DAC: low byte on P0, high byte on P2
 *     (counts, 1 count a step). The port latches come out of reset at FFh, and a DAC fed by
 *     them would drive 65535: the firmware writes it before it converts anything (a
 *     calibration, or "accept and run" if no calibration came since reset). (The emulator's
 *     plant sees the DAC only once the firmware first writes its latches.)
 *
 * Configuration block at FF00h (21 bytes; see configs/firmware/harvester/d0.ron):
 *   FF00h      layout version, 01h
 *   FF01h      node address, D0h-D5h
 *   FF02h-05h  CANIDT1-4 of the receive channels: identifier 0601<address>F5 << 3
 *   FF06h-09h  CANIDT1-4 of the transmit channel: identifier 0601F5<address> << 3
 *              (both must carry the address of FF01h)
 *   FF0Ah-0Bh  boot delay, ms from reset to the end of boot, little-endian (1-65535)
 *   FF0Ch      phase of the groups in their 100 ms period, ms (0-99)
 *   FF0Dh-11h  ADC channel (0-7) of units 1-5
 *   FF12h      P1 pins of the multiplexers' select lines (mask; none of the units' channels)
 *   FF13h      P3 pins of the multiplexers' select lines (mask)
 *   FF14h      checksum: the 21 bytes FF00h-FF14h add up to 00h (mod 256)
 * A block that fails these checks (a chip nobody configured reads FFh there) leaves the node
 * off the bus: it never sends.
 *
 * Timing: timer 2 ticks every 10 ms (auto-reload from RCAP2 = 65536 - 10000), on a grid the
 * start-up code aligns from the configuration block (TL2/TH2 loaded before it starts): the
 * ticks fall on the node's group points, boot end + phase + n x 10 ms, so that the groups
 * (every tenth tick) and the acknowledgements' 50 ms time-out (five ticks) fall on ticks. The
 * script checks the status every 20 ms and sends it at least every 250 ms on its own grid,
 * boot end + n x 10 ms (whose first point is the end of boot), and so does the firmware: its
 * "status points" lie (10 - phase mod 10) mod 10 ms after each tick. Where that is 0 (phase 0
 * or 80: D0, D5) the tick does the status point itself. Otherwise the firmware works out at
 * each tick, and again after each received frame, whether the coming status point sends
 * anything (boot ends there, the heartbeat falls due, or it is a 20 ms check and the state or
 * missed_acks differ from the last status sent), and only then wakes for it, by timer 0 as a
 * one-shot; a point nobody woke for sends nothing, and is counted when the main loop gets to
 * whatever comes after it. So the CPU wakes 100 times a second for the ticks and a few times
 * more for the status frames it sends (and for the CAN interrupts).
 * Received frames are copied out by the CAN interrupt with the time it took them (the tick
 * they follow, and whether they came after its status point) and acted on by the main loop as
 * soon as it sees them, not at the next tick. The main loop takes frames, status points and
 * ticks in the order they came, however late it gets to them: a frame that came just before a
 * status point is reported by it, one that came just before a tick counts before the tick's
 * acknowledgement time-outs. A tick's work runs in the script's order: acknowledgements
 * overdue, the status point (offset 0), the flow group, the reference group.
 * Frames go out in the order they were made
 * through one transmit channel, fed by the CAN interrupt from a queue of 16 (the script's
 * controller queue); a frame that finds the queue full is dropped. After bus off the main
 * loop restarts the controller (general reset, then the whole set-up) and sends the frame it
 * was sending again, as c0_alarm.c does.
 *
 * Build (in this folder; the HEX is configs/firmware/flow_sensor.hex):
 *   sdcc -mmcs51 --model-small -o flow_sensor.ihx flow_sensor.c
 *   packihx flow_sensor.ihx > ../flow_sensor.hex
 */
#include "../c0/at89c51cc03.h"

/* ---- Configuration block ---- */

#define CFG_SIZE 21
#define CFG_VERSION 0x01
#define CFG_VERSION_AT 0
#define CFG_ADDRESS_AT 1
#define CFG_RX_IDT_AT 2
#define CFG_TX_IDT_AT 6
#define CFG_BOOT_AT 10
#define CFG_PHASE_AT 12
#define CFG_CHANNELS_AT 13
#define CFG_SELECT_P1_AT 18
#define CFG_SELECT_P3_AT 19

/* Placed by the node file, not by this image. */
__code __at(0xFF00) unsigned char cfg[CFG_SIZE];

/* ---- Constants of the script ---- */

#define FIRMWARE_VERSION 3
#define CHECK_MS 20        /* status: checked every 20 ms */
#define HEARTBEAT_MS 250   /* status: sent at least every 250 ms */
#define GROUP_PERIOD_MS 100
#define ACK_TIMEOUT_MS 50
/* The same in ticks (groups, time-outs) and status points (status), both 10 ms apart. */
#define CHECK_POINTS (CHECK_MS / TICK_MS)
#define HEARTBEAT_POINTS (HEARTBEAT_MS / TICK_MS)
#define GROUP_TICKS (GROUP_PERIOD_MS / TICK_MS)
#define ACK_TIMEOUT_TICKS (ACK_TIMEOUT_MS / TICK_MS)
#define ACK_LIMIT 3
#define UNITS 5

/* States, as flow.status codes them. */
#define ST_AWAITING 1
#define ST_CALIBRATING 2
#define ST_RUNNING 3
#define ST_NO_ACK 4

/* Message numbers (Data0) and group codes. */
#define MSG_MARKER 0x20
#define MSG_PART1 0x01
#define MSG_PART2 0x02
#define MSG_STATUS 0x30
#define MSG_CALIBRATE 0x10
#define MSG_ACK 0x21
#define GROUP_FLOW 0x0D
#define GROUP_REFERENCE 0x0E
#define DLC_CALIBRATE 5
#define DLC_ACK 3

/* ---- Timer 2: the 10 ms tick; timer 0: the status point ---- */

/* Timer 2 counts machine cycles (1 us): 10 000 counts are 10 ms. */
#define TICK_MS 10
#define TICK_RELOAD (65536u - 10000u)
/* Machine cycles from reset until timer 2 counts its first cycle (the reset jump, the start
 * code's stack set-up and call, and the start-up function below up to its start of timer 2),
 * so that the first tick falls exactly where the start-up function puts it. It takes the same
 * time whatever the configuration block holds. The C start-up code clears the internal RAM
 * in 0.8 ms, and main enables the tick interrupt before anything else: no overflow is lost. */
#define CYCLES_BEFORE_RUN 84u
/* Timer 2 counts for the first tick r ms after reset (r = 1-10), by r mod 10. */
#define FIRST_TICK(r) (65536u - (r) * 1000u + CYCLES_BEFORE_RUN)
static __code const unsigned char first_tick_lo[10] = {
    FIRST_TICK(10) & 0xFF, FIRST_TICK(1) & 0xFF, FIRST_TICK(2) & 0xFF, FIRST_TICK(3) & 0xFF,
    FIRST_TICK(4) & 0xFF, FIRST_TICK(5) & 0xFF, FIRST_TICK(6) & 0xFF, FIRST_TICK(7) & 0xFF,
    FIRST_TICK(8) & 0xFF, FIRST_TICK(9) & 0xFF};
static __code const unsigned char first_tick_hi[10] = {
    FIRST_TICK(10) >> 8, FIRST_TICK(1) >> 8, FIRST_TICK(2) >> 8, FIRST_TICK(3) >> 8,
    FIRST_TICK(4) >> 8, FIRST_TICK(5) >> 8, FIRST_TICK(6) >> 8, FIRST_TICK(7) >> 8,
    FIRST_TICK(8) >> 8, FIRST_TICK(9) >> 8};

/* Ticks since reset (mod 256), counted by the timer 2 interrupt, and those the main loop has
 * done. */
volatile unsigned char ticks;
static unsigned char seen;

/* Timer 0 (16-bit, mode 1) wakes the main loop at a status point between two ticks: the
 * interrupt stops it and raises status_due. Machine cycles from reading timer 2 to timer 0
 * counting its first cycle in status_arm(), so that timer 0 overflows at the status point
 * itself (as --trace-cpu shows: its interrupt is entered at the point as timer 2's is at a
 * tick). */
#define ARM_CYCLES 59u
/* A status point this close (machine cycles), or closer than timer 0 could be set for, is taken
 * at once rather than waited for. */
#define STATUS_NEAR (ARM_CYCLES + 20u)
volatile __bit status_due;
static __bit t0_armed;

/* ---- CAN channels ---- */

/* Two receive channels with the same filter (the lowest free one takes a frame, so a second
 * frame that comes before the first is copied out is not lost) and one transmit channel. */
#define RX_CHANNEL_A 0
#define RX_CHANNEL_B 1
#define TX_CHANNEL 2
#define CHANNELS 15

/* The queues are in the on-chip XRAM at fixed addresses, which the C start-up code does not
 * clear: they need no clearing, and it would take 1.3 ms before the tick interrupt is
 * enabled (see timer 2 above). */

/* Received frames, copied out by the CAN interrupt: DLC and the first five data bytes (the
 * longest frame the sensor takes, flow.calibrate, has five), and when it came: the tick it
 * followed (ticks since reset, mod 256) and whether it came after that tick's status point.
 * The main loop takes each frame, tick and status point in that order, however late it gets
 * to them. */
#define RXQ 4
#define RX_BYTES 5
__xdata __at(0x0000) unsigned char rxq_dlc[RXQ];
__xdata __at(0x0004) unsigned char rxq_data[RXQ][RX_BYTES];
__xdata __at(0x00A8) unsigned char rxq_tick[RXQ];
__xdata __at(0x00AC) unsigned char rxq_after[RXQ];
/* Frames put in (by the interrupt only) and taken out (by the main loop only), counted mod
 * 256: each side writes its own count, so neither needs the other held off. */
volatile unsigned char rxq_in, rxq_out;

/* Frames to send, oldest first; the oldest is in the transmit channel while tx_busy. Put in
 * by the main loop only, taken out by the interrupt (and the bus-off restart, with the
 * interrupt masked) only, counted mod 256 as the receive queue is. */
#define TXQ 16
__xdata __at(0x0018) unsigned char txq_dlc[TXQ];
__xdata __at(0x0028) unsigned char txq_data[TXQ][8];
volatile unsigned char txq_in, txq_out;
volatile __bit tx_busy;
/* Frames dropped because the queue was full. */
unsigned int tx_dropped;
/* Times the CAN controller was restarted after bus-off. */
unsigned int can_restarts;

/* ---- The node's state ---- */

static unsigned char channel[UNITS];
static unsigned char select_p1, select_p3;
static unsigned char analog_pins; /* P1 pins of the units' channels */
static unsigned int boot_left;   /* status points until the one that ends boot, that one too */
static unsigned char phase;
/* Where a tick's status point lies after it: timer 2's count there (RCAP2: at the tick). */
static unsigned int status_at;
static __bit status_offset;     /* the status points lie between the ticks */
static __bit point_done;        /* the status point after the last tick (point 0 before the
                                 * first tick) is done */
static __bit booted;
static unsigned char state;
/* Acknowledgements: groups sent and not yet answered, ticks until they are overdue (they all
 * went out on one tick: a group is overdue after 50 ms and the next goes 100 ms after it),
 * groups missed in a row (saturating), and the state given up in. */
static unsigned char awaited;
static unsigned char due_left;
static unsigned char missed;
static __bit gave_up;
static unsigned char gave_up_from;
/* Status: status points (10 ms apart) to the next check, points since the last send, and what
 * that send said. */
static unsigned char check_left;
static unsigned char since_status;
static __bit status_sent;
static unsigned char sent_state, sent_missed;
/* Groups: ticks to the next point of the 100 ms grid. */
static unsigned char group_left;
/* The DAC holds a target the monitor sent (not its reset value). */
static __bit dac_set;
/* One group's five values, counts, low and high bytes. */
static unsigned char value_lo[UNITS], value_hi[UNITS];

/* Starts timer 2 before the C start-up code clears RAM, so that ticks count from reset, on
 * the node's grid: the first tick (boot delay + phase) mod 10 ms after reset (10 ms for 0).
 * 256 is 6 mod 10, so (hi x 256 + lo + phase) mod 10 is (hi mod 10 x 6 + lo mod 10 + phase
 * mod 10) mod 10: four DIV AB, one MUL AB and two table reads, the same cycles whatever the
 * block holds (a block the checks in main refuse stops the timer again). */
unsigned char _sdcc_external_startup(void)
{
    unsigned char hi = cfg[CFG_BOOT_AT + 1], lo = cfg[CFG_BOOT_AT], ph = cfg[CFG_PHASE_AT], r;

    /* Unsigned char operands all through: DIV AB, not the library's 16-bit division. */
    r = (unsigned char)(hi % (unsigned char)10) * (unsigned char)6;
    r += (unsigned char)(lo % (unsigned char)10);
    r += (unsigned char)(ph % (unsigned char)10);
    r = r % (unsigned char)10;
    RCAP2L = TICK_RELOAD & 0xFF;
    RCAP2H = TICK_RELOAD >> 8;
    TL2 = first_tick_lo[r];
    TH2 = first_tick_hi[r];
    T2CON = T2CON_TR2;
    return 0;
}

void timer2_isr(void) __interrupt(5)
{
    TF2 = 0;
    ticks++;
}

/* A status point between two ticks: timer 0 is a one-shot. */
void timer0_isr(void) __interrupt(1)
{
    TR0 = 0;
    status_due = 1;
}

/* Hands the oldest queued frame to the transmit channel, which is on the page (INDX 0,
 * moving on after each byte). A macro: the CAN interrupt calls no function, so that it saves
 * only the registers it uses and the next frame goes out soon after the last. */
#define TX_LOAD()                                                              \
    do {                                                                       \
        unsigned char slot_ = txq_out & (TXQ - 1);                             \
        unsigned char n_ = txq_dlc[slot_];                                     \
        unsigned char i_ = n_; /* 4 or 8 */                                    \
        __xdata unsigned char *d_ = txq_data[slot_];                           \
        do                                                                     \
            CANMSG = *d_++;                                                    \
        while (--i_);                                                          \
        CANSTCH = 0;                                                           \
        CANCONCH = CANCONCH_TX | CANCONCH_IDE | n_;                            \
        tx_busy = 1;                                                           \
    } while (0)

/* The same, called with the CAN interrupt masked. */
static void tx_load(void)
{
    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL);
    TX_LOAD();
}

/* Copies a frame out of the receive channel on the page, if it has one, with the time the
 * interrupt found it at (the tick last counted, or the next one if timer 2 has overflowed
 * since: its interrupt waits for this one; and whether that tick's status point has passed),
 * and enables the channel again. */
#define RX_TAKE()                                                              \
    do {                                                                       \
        if (CANSTCH & CANSTCH_RXOK) {                                          \
            if ((unsigned char)(rxq_in - rxq_out) < RXQ) {                     \
                unsigned char slot = rxq_in & (RXQ - 1);                       \
                __xdata unsigned char *d = rxq_data[slot];                     \
                unsigned char h, l, at_tick;                                   \
                __bit wrapped;                                                 \
                do {                                                           \
                    h = TH2;                                                   \
                    l = TL2;                                                   \
                    wrapped = TF2;                                             \
                } while (h != TH2);                                            \
                at_tick = ticks;                                               \
                if (wrapped)                                                   \
                    at_tick++;                                                 \
                rxq_tick[slot] = at_tick;                                      \
                rxq_after[slot] = (((unsigned int)h << 8) | l) >= status_at;   \
                rxq_dlc[slot] = CANCONCH & 0x0F;                               \
                d[0] = CANMSG;                                                 \
                d[1] = CANMSG;                                                 \
                d[2] = CANMSG;                                                 \
                d[3] = CANMSG;                                                 \
                d[4] = CANMSG;                                                 \
                rxq_in++;                                                      \
            }                                                                  \
            CANSTCH = 0;                                                       \
            CANCONCH = CANCONCH_RX | CANCONCH_IDE | 8;                         \
        }                                                                      \
    } while (0)

/* The CAN interrupt's own: bytes left to copy, and CANCONCH of the frame it copies. */
static unsigned char isr_left, isr_conch;

/* The CAN interrupt: a frame sent lets the next one go (first, so that the bus waits least:
 * TX_LOAD() in assembler, a DJNZ loop of 7 machine cycles a byte with the pointer in DPTR),
 * frames received are copied out (channel A before B: a frame goes to the lowest free
 * channel, so A's came first). It calls no function and works in register bank 1, so that it
 * saves only ACC, B, DPTR and PSW. */
void can_isr(void) __interrupt(7) __using(1)
{
    unsigned char page = CANPAGE;

    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL);
    if (CANSTCH & CANSTCH_TXOK) {
        CANSTCH = 0;
        tx_busy = 0;
        txq_out++;
        if (txq_out != txq_in) {
            /* The queue is in the first 256 bytes of XRAM: DPH is 0. */
            __asm
                mov     a,_txq_out
                anl     a,#0x0f                 ; the slot (16 of them)
                mov     b,a
                add     a,#_txq_dlc
                mov     dpl,a
                mov     dph,#(_txq_dlc >> 8)
                movx    a,@dptr                 ; its DLC
                mov     _isr_left,a
                orl     a,#0x50                 ; transmit, extended identifier, DLC
                mov     _isr_conch,a
                mov     a,b
                swap    a
                rr      a                       ; slot x 8
                add     a,#_txq_data
                mov     dpl,a
                mov     dph,#(_txq_data >> 8)
            00001$:
                movx    a,@dptr
                mov     _CANMSG,a
                inc     dptr
                djnz    _isr_left,00001$
                mov     _CANSTCH,#0x00
                mov     _CANCONCH,_isr_conch
            __endasm;
            tx_busy = 1;
        }
    }
    CANPAGE = CANPAGE_CHANNEL(RX_CHANNEL_A);
    RX_TAKE();
    CANPAGE = CANPAGE_CHANNEL(RX_CHANNEL_B);
    RX_TAKE();
    CANPAGE = page;
}

/* The receive filter on the page's channel: the identifier the monitor addresses this node
 * with, every identifier bit, RTR and IDE compared. */
static void rx_setup(void)
{
    CANIDT1 = cfg[CFG_RX_IDT_AT];
    CANIDT2 = cfg[CFG_RX_IDT_AT + 1];
    CANIDT3 = cfg[CFG_RX_IDT_AT + 2];
    CANIDT4 = cfg[CFG_RX_IDT_AT + 3];
    CANIDM1 = 0xFF;
    CANIDM2 = 0xFF;
    CANIDM3 = 0xFF;
    CANIDM4 = 0xFD;
    CANSTCH = 0;
    CANCONCH = CANCONCH_RX | CANCONCH_IDE | 8;
}

/* The whole CAN set-up, after a general reset: used at start and after bus-off. Called with
 * the CAN interrupt masked. A frame the queue still holds (the one being sent when the
 * controller went bus off) goes out again. */
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

    CANPAGE = CANPAGE_CHANNEL(RX_CHANNEL_A);
    rx_setup();
    CANPAGE = CANPAGE_CHANNEL(RX_CHANNEL_B);
    rx_setup();

    /* The transmit channel: identifier 0601F5<address> << 3, data frames (RTRTAG 0). */
    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL);
    CANIDT1 = cfg[CFG_TX_IDT_AT];
    CANIDT2 = cfg[CFG_TX_IDT_AT + 1];
    CANIDT3 = cfg[CFG_TX_IDT_AT + 2];
    CANIDT4 = cfg[CFG_TX_IDT_AT + 3];

    /* Interrupts: reception and transmission, on the three channels. */
    CANGIE = 0x30; /* ENRX, ENTX */
    CANIE1 = 0;
    CANIE2 = (1 << RX_CHANNEL_A) | (1 << RX_CHANNEL_B) | (1 << TX_CHANNEL);

    tx_busy = 0;
    CANGCON = CANGCON_ENA;
    if (txq_out != txq_in)
        tx_load();
}

/* A free slot at the end of the transmit queue, or 0 when it is full. */
static __xdata unsigned char *txq_slot(void)
{
    if ((unsigned char)(txq_in - txq_out) >= TXQ) {
        tx_dropped++;
        return 0;
    }
    return txq_data[txq_in & (TXQ - 1)];
}

/* Queues the frame written into the slot txq_slot gave, and starts it if the channel is
 * free. */
static void txq_commit(unsigned char dlc)
{
    txq_dlc[txq_in & (TXQ - 1)] = dlc;
    txq_in++;
    ECAN = 0;
    if (!tx_busy)
        tx_load();
    ECAN = 1;
}

/* ---- The plant ---- */

/* The five units' values (references = 0) or references (references = 1), counts, into
 * value_lo/value_hi. The 10-bit code c is ADDH (bits 9-2) and ADDL (bits 1-0); a value is
 * c x 64 = ADDH:ADDL<<6, a reference c x 16 = (ADDH:ADDL<<6) >> 2. */
static void sample(unsigned char references)
{
    unsigned char k, h, l;

    if (references) {
        P1 |= select_p1;
        P3 |= select_p3;
    } else {
        P1 &= ~select_p1;
        P3 &= ~select_p3;
    }
    for (k = 0; k < UNITS; k++) {
        ADCON = ADCON_ADEN | ADCON_ADSST | channel[k];
        while (!(ADCON & ADCON_ADEOC))
            ;
        ADCON = ADCON_ADEN;
        h = ADDH;
        l = (ADDL & 0x03) << 6;
        if (references) {
            value_hi[k] = h >> 2;
            value_lo[k] = (h << 6) | (l >> 2);
        } else {
            value_hi[k] = h;
            value_lo[k] = l;
        }
    }
}

/* Drives the emitters to `target` counts: low byte, then high byte. */
static void dac_write(unsigned int target)
{
    P0 = target & 0xFF;
    P2 = target >> 8;
    dac_set = 1;
}

/* ---- The protocol ---- */

/* Sends one group: its marker, then (while the marker goes out) the five values sampled,
 * in part1 and part2; and awaits its acknowledgement. */
static void send_group(unsigned char group)
{
    __xdata unsigned char *d;

    d = txq_slot();
    if (d) {
        d[0] = MSG_MARKER;
        d[1] = group;
        d[2] = 0x00;
        d[3] = 0x02;
        d[4] = 0xFF;
        d[5] = 0xCC - group; /* BF for flow, BE for references */
        d[6] = 0xFF;
        d[7] = 0x00;
        txq_commit(8);
    }
    sample(group == GROUP_REFERENCE);
    d = txq_slot();
    if (d) {
        d[0] = MSG_PART1;
        d[1] = 1; /* status: running */
        d[2] = value_lo[0];
        d[3] = value_hi[0];
        d[4] = value_lo[1];
        d[5] = value_hi[1];
        d[6] = value_lo[2];
        d[7] = value_hi[2];
        txq_commit(8);
    }
    d = txq_slot();
    if (d) {
        d[0] = MSG_PART2;
        d[1] = value_lo[3];
        d[2] = value_hi[3];
        d[3] = value_lo[4];
        d[4] = value_hi[4];
        if (group == GROUP_FLOW) {
            d[5] = 0x90; /* aux 16739984 = FF6E90h */
            d[6] = 0x6E;
            d[7] = 0xFF;
        } else {
            d[5] = 0x44; /* aux 7263300 = 6ED444h */
            d[6] = 0xD4;
            d[7] = 0x6E;
        }
        txq_commit(8);
    }
    awaited++;
    due_left = ACK_TIMEOUT_TICKS;
}

static void send_status(void)
{
    __xdata unsigned char *d = txq_slot();

    sent_state = state;
    sent_missed = missed;
    status_sent = 1;
    since_status = 0;
    if (d) {
        d[0] = MSG_STATUS;
        d[1] = state;
        d[2] = FIRMWARE_VERSION;
        d[3] = missed;
        txq_commit(4);
    }
}

/* An acknowledgement: every group sent so far is answered; a sensor that gave up goes back to
 * the state it gave up in. */
static void acknowledged(void)
{
    awaited = 0;
    missed = 0;
    if (gave_up) {
        gave_up = 0;
        if (state == ST_NO_ACK)
            state = gave_up_from;
    }
}

/* A frame from the monitor, from the receive queue. */
static void react(unsigned char dlc, __xdata unsigned char *d)
{
    if (d[0] == MSG_CALIBRATE && dlc == DLC_CALIBRATE) {
        unsigned int target = d[2] | ((unsigned int)d[3] << 8);
        switch (d[1]) {
        case 0: /* stop */
            state = ST_AWAITING;
            break;
        case 1: /* start calibration */
            dac_write(target);
            acknowledged();
            state = ST_CALIBRATING;
            break;
        case 2: /* accept and run */
            /* The emitters must not run from the DAC's reset value: a sensor told to run
             * without a calibration since reset takes the target this command carries. */
            if (!dac_set)
                dac_write(target);
            acknowledged();
            state = ST_RUNNING;
            break;
        default:
            break;
        }
    } else if (d[0] == MSG_ACK && dlc == DLC_ACK) {
        acknowledged();
    }
}

/* A status point: boot ends at the one boot_left counts to; after boot, the status goes out
 * when it is due. A point nobody woke for (status_needed() found it sends nothing) is done
 * when the main loop gets to the next thing after it. */
static void status_point(void)
{
    __bit checking;

    if (!booted) {
        if (--boot_left)
            return;
        /* Boot is over: the status check grid starts here, the group grid phase ms on. */
        booted = 1;
        state = ST_AWAITING;
        check_left = 0;
        group_left = phase / TICK_MS;
    }
    checking = (check_left == 0);
    if (checking)
        check_left = CHECK_POINTS;
    check_left--;
    if (since_status != 0xFF)
        since_status++;
    if (!status_sent || since_status >= HEARTBEAT_POINTS
        || (checking && (state != sent_state || missed != sent_missed)))
        send_status();
}

/* The status point after the last tick, now: and no wake for it any more. */
static void do_point(void)
{
    TR0 = 0;
    TF0 = 0;
    status_due = 0;
    t0_armed = 0;
    status_point();
    point_done = 1;
}

/* Whether the coming status point sends (or ends boot), as things stand. */
static __bit status_needed(void)
{
    if (!booted)
        return boot_left == 1;
    return !status_sent || since_status >= HEARTBEAT_POINTS - 1
           || (check_left == 0 && (state != sent_state || missed != sent_missed));
}

/* Wakes the main loop at the coming status point (timer 0), or does the point now when it is
 * there or has passed (the main loop is late: a tick, or a frame that came before the point,
 * took it past it). */
static void status_arm(void)
{
    unsigned char h, l;
    unsigned int now;

    do {
        h = TH2;
        l = TL2;
    } while (h != TH2);
    now = ((unsigned int)h << 8) | l;
    if (TF2 || seen != ticks || now >= status_at - STATUS_NEAR) {
        do_point();
        return;
    }
    now = status_at - now - ARM_CYCLES; /* cycles to wait */
    now = -now;
    TL0 = now & 0xFF;
    TH0 = now >> 8;
    TR0 = 1;
    t0_armed = 1;
}

/* After a frame that came before the coming status point: a change the point must report
 * wakes it. */
static void status_recheck(void)
{
    if (status_offset && !point_done && !t0_armed && status_needed())
        status_arm();
}

/* The work of one 10 ms tick. */
static void tick(void)
{
    __bit group_due;

    /* The main loop did the status point before this tick: the next one is ahead. */
    point_done = 0;

    /* Acknowledgements overdue by now count before anything is sent: a sensor that gives up
     * sends nothing more of its groups. */
    if (booted && awaited && --due_left == 0) {
        while (awaited) {
            awaited--;
            if (missed != 0xFF)
                missed++;
            if (missed >= ACK_LIMIT && state != ST_NO_ACK) {
                gave_up = 1;
                gave_up_from = state;
                state = ST_NO_ACK;
            }
        }
    }

    /* Status: on a change found by the 20 ms check, and 250 ms after the last send. */
    if (!status_offset)
        do_point();

    /* Groups, on the 100 ms grid: flow first, then references. */
    if (booted) {
        group_due = (group_left == 0);
        if (group_due)
            group_left = GROUP_TICKS;
        group_left--;
        if (group_due) {
            if (state == ST_RUNNING)
                send_group(GROUP_FLOW);
            if (state == ST_CALIBRATING || state == ST_RUNNING)
                send_group(GROUP_REFERENCE);
        }
    }

    /* The status point before the next tick: wake for it if it sends. */
    if (status_offset && status_needed())
        status_arm();
}

/* Bit n, for n = 0-7 (a shift by a variable count costs a loop). */
static __code const unsigned char bit_of[8] = {0x01, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40, 0x80};

/* Takes the node's settings from the configuration block; false when the block is not there
 * or not whole. */
static __bit configure(void)
{
    __code unsigned char *p = cfg;
    unsigned char i, sum = 0;

    for (i = CFG_SIZE; i; i--)
        sum += *p++;
    if (sum != 0 || cfg[CFG_VERSION_AT] != CFG_VERSION || cfg[CFG_PHASE_AT] >= GROUP_PERIOD_MS)
        return 0;
    boot_left = cfg[CFG_BOOT_AT] | ((unsigned int)cfg[CFG_BOOT_AT + 1] << 8);
    if (boot_left == 0)
        return 0;
    /* The identifiers must be this node's: the address is ID15..8 of the one received (ID18..11
     * of CANIDT, bits 2-0 of CANIDT2 and 7-3 of CANIDT3) and ID7..0 of the one sent (bits 2-0
     * of CANIDT3 and 7-3 of CANIDT4). */
    i = cfg[CFG_ADDRESS_AT];
    if ((unsigned char)((cfg[CFG_RX_IDT_AT + 1] << 5) | (cfg[CFG_RX_IDT_AT + 2] >> 3)) != i
        || (unsigned char)((cfg[CFG_TX_IDT_AT + 2] << 5) | (cfg[CFG_TX_IDT_AT + 3] >> 3)) != i)
        return 0;
    phase = cfg[CFG_PHASE_AT];
    /* The grids, as the start-up code set timer 2: ticks at boot + phase + n x 10 ms, tick 1
     * first ms after reset (1-10), so tick n at first + (n - 1) x 10 ms (tick 0 at or before
     * reset); status points at boot + n x 10 ms, point n off ms after tick n. Boot ends at
     * point (boot + 10 - first - off) / 10, and the points are counted from point 0, which is
     * done before tick 1 (it only counts: it may lie before reset). Before tick 1, and from
     * each tick to its status point, timer 2 counts up from RCAP2 as if from a tick. */
    {
        unsigned char first = (unsigned char)(boot_left % TICK_MS + phase % TICK_MS) % TICK_MS;
        unsigned char off = (TICK_MS - phase % TICK_MS) % TICK_MS;
        if (first == 0)
            first = TICK_MS;
        boot_left = (unsigned int)(((unsigned long)boot_left + TICK_MS - first - off) / TICK_MS);
        boot_left++;
        status_offset = (off != 0);
        status_at = TICK_RELOAD + (unsigned int)off * 1000u;
    }
    analog_pins = 0;
    for (i = 0; i < UNITS; i++) {
        unsigned char ch = cfg[CFG_CHANNELS_AT + i];
        if (ch > 7)
            return 0;
        channel[i] = ch;
        analog_pins |= bit_of[ch];
    }
    select_p1 = cfg[CFG_SELECT_P1_AT];
    select_p3 = cfg[CFG_SELECT_P3_AT];
    /* A select line on a unit's own pin would switch its input. */
    return (select_p1 & analog_pins) == 0;
}

void main(void)
{
    /* The tick first: the rest of the start runs while it counts. */
    ET2 = 1;
    EA = 1;
    if (!configure()) {
        EA = 0;
        TR2 = 0;
        for (;;)
            ; /* not configured: stay off the bus */
    }

    ADCF = analog_pins; /* the units' pins are analog inputs */
    ADCLK = 0x03; /* ADC clock 6 MHz / (4 x 3) = 500 kHz */
    ADCON = ADCON_ADEN;
    can_setup();
    TMOD = 0x01; /* timer 0: 16-bit, counting machine cycles, stopped */
    ET0 = 1;
    ECAN = 1;
    /* The status point before the first tick ends boot when the boot delay is that short. */
    if (status_offset && status_needed())
        status_arm();

    for (;;) {
        /* Idle until a frame, a tick or a status point. */
        while (seen == ticks && !status_due && rxq_out == rxq_in) {
            if (CANGSTA & CANGSTA_BOFF) {
                ECAN = 0;
                can_setup();
                ECAN = 1;
                can_restarts++;
            }
        }
        /* Frames that came before the next tick, oldest first, acted on at once; the status
         * point goes before the first that came after it. Before boot ends they are dropped. */
        while (rxq_out != rxq_in) {
            unsigned char slot = rxq_out & (RXQ - 1);
            if (rxq_tick[slot] != seen)
                break;
            if (rxq_after[slot] && !point_done)
                do_point();
            if (booted)
                react(rxq_dlc[slot], rxq_data[slot]);
            rxq_out++;
            status_recheck();
        }
        if (status_due) {
            if (point_done)
                status_due = 0;
            else
                do_point();
        }
        if (seen != ticks) {
            if (!point_done)
                do_point();
            seen++;
            tick();
        }
    }
}
