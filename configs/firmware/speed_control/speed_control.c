/*
 * speed_control.c: the travel speed control module (E0) as AT89C51CC03 firmware.
 *
 * It behaves on the bus as the script node configs/nodes/e0.ron:
 *   - After its boot delay it sends speed.status (Data0 10h, DLC 7) every 50 ms, the first at
 *     boot end + phase: the travel speed measured (u16, 0.01 km/h), the set-point in force
 *     (u16, 0.01 km/h) and the drive mode (0 manual, 1 cruise, 2 unloading) as the machine
 *     reports them, operator_override 0 and setpoint_timeout (Data6 bit 1).
 *   - It takes the monitor's speed.mode (01h, DLC 2), speed.setpoint (02h, DLC 3) and
 *     speed.unload (03h, DLC 2); any other Data0, DLC or value is ignored, as are frames before
 *     boot end. Its own state (manual, cruise, unloading) decides only the watchdog:
 *       mode 1       cruise requested; setpoint_timeout 0; manual/unloading -> cruise.
 *       mode 0       cruise request off; -> manual.
 *       setpoint     the set-point to the drive, whatever the state (one above 12.00 km/h
 *                    is not driven: the drive refuses it and keeps the last); setpoint_timeout
 *                    0; in cruise the watchdog starts again.
 *       unload 1     unload on (stop, raise the basket); -> unloading.
 *       unload 0     unload off and cruise request off; -> manual.
 *   - The watchdog: 1000 ms in cruise without a set-point (counted from entering cruise or from
 *     the last set-point) drops the cruise request, sets setpoint_timeout and goes manual.
 *
 * Hardware, as the firmware node file (configs/firmware/harvester/e0.ron) wires it:
 *   - 12 MHz crystal, X1 mode: a machine cycle is 1 us; F_CAN = 6 MHz.
 *   - ADC (VAREF = 5000 mV): channel 0 (P1.0) the travel speed speed.actual and channel 1
 *     (P1.1) the set-point in force speed.setpoint_in_force, each 5000/12 mV per km/h from
 *     half a code (5000/2048 mV) up, so 0..12 km/h fill the converter's range, a code is
 *     12/1024 km/h, and a speed falls in the code nearest to it (0 km/h in the middle of code
 *     0). The firmware takes a code c for the centre of its bin, less the half code:
 *     c x 1200/1024 in 0.01 km/h, rounded; 12.00 km/h, at the top of code 1023, reads 11.99.
 *     Channel 2 (P1.2) the drive mode speed.mode at 500 mV + 2000 mV per unit: 500, 2500 and
 *     4500 mV for 0, 1 and 2 (codes 102, 512, 921; read with thresholds at codes 307 and 717).
 *   - The set-point speed.setpoint: a 16-bit DAC on P0 (low byte) and P2 (high byte), the code
 *     in the protocol's 0.01 km/h; written low byte first, the two writes 1 us apart.
 *   - The cruise request speed.mode_request on P3.4 and the unload command speed.unload on P3.5,
 *     both active low (the driver is on while the pin is low), so that the pins' reset state,
 *     high, is off. The DAC is written 0 at once after reset (its reset code FFFFh is out of
 *     the drive's range, which refuses it).
 *   - CAN at 250 kbit/s on the on-chip controller (TxDC/RxDC).
 *
 * Timing: timer 2 in auto-reload mode ticks every 10 ms (10 000 machine cycles) on a grid laid
 * on the node's own schedule: the first tick falls at boot end + phase (51 ms), when the first
 * status is due, and every status falls on a tick (50 ms are 5 ticks). Before that first tick
 * the timer overflows only to count the boot: once at boot end (50 ms), and before it as many
 * times as a boot longer than the timer's 65 ms would need (none here); the interrupt routine
 * plans each of those periods one overflow ahead through RCAP2, which the timer loads at its
 * overflow, so every overflow falls on its machine cycle whatever the program is doing. The
 * main loop sets the timer's count once, before the first overflow (timer2_advance()).
 * The main loop handles every tick in turn: the status when it is due, then the watchdog,
 * which counts whole ticks: started between ticks k - 1 and k (a command between boot end and
 * the first tick, tick 0, starts it between ticks -1 and 0), it fires on tick k - 1 + 100, the
 * tick at or before its exact time (the last one before it, or the one on it). A status is
 * sampled on its tick before the watchdog's turn, so it shows the watchdog's work exactly when
 * a timer running to the microsecond would have done it before the status was due, as the
 * script's does: a watchdog whose exact time falls between two statuses fires on a tick before
 * the later one (at the latest on the tick before it), one whose exact time falls after a
 * status fires after it was sampled (on its tick or later).
 *
 * CAN: receive object 0 takes the monitor's commands (its filter from the configuration block);
 * its interrupt copies each frame that comes after boot end into a small queue, with the tick
 * count at its arrival, and enables the object again at once, so that no command is lost while
 * the main loop is busy (the monitor sends speed.mode and speed.setpoint back to back); frames
 * before boot end it drops. The main loop acts on the queue as soon as a frame is in it,
 * between ticks, not at the next tick: in order of arrival, and a tick that came before a
 * frame is handled before that frame (so a watchdog the frame starts counts from that tick
 * on). Transmit object 1 sends the status, at once on its tick. A status due while the one
 * before is still waiting for the bus is sent as soon as the object is free (the main loop
 * then watches the object between ticks; the newest sample wins). Between ticks the main loop
 * polls CANGSTA.BOFF; after bus off it restarts the controller (general reset, then the whole
 * set-up again), counts the restart in can_restarts and sends again, at once, the frame the
 * controller lost, as c0_alarm.c does.
 *
 * CONFIGURATION BLOCK at FF00h (18 bytes; 16-bit values little-endian), supplied by the node
 * file (`config: (at: 0xFF00, bytes: [...])`); this source only declares it:
 *   +00      45h ('E'): a speed control block. Anything else (an erased FFh, another kind's
 *            block) and the firmware never starts its CAN controller: the node stays silent
 *            with its outputs off (manual, no unload, set-point 0).
 *   +01      the node's address (E0h). The firmware checks it against the identifiers below
 *            (source byte of the transmit identifier, destination byte of the receive one) and
 *            treats a block that disagrees as a missing one.
 *   +02..05  CANIDT1-4 of the transmit object: speed.status's 29-bit identifier shifted left by
 *            3 (RTRTAG 0: a data frame): 0200F5E0 -> 10 07 AF 00.
 *   +06..09  CANIDT1-4 of the receive object: the commands' identifier shifted left by 3:
 *            0200E0F5 -> 10 07 07 A8.
 *   +0A..0D  CANIDM1-4 of the receive object: FF FF FF FD compares every identifier bit,
 *            RTRMSK and IDEMSK (extended data frames with exactly that identifier).
 *   +0E..0F  boot delay, ms from reset (50). Frames before boot end are ignored.
 *   +10..11  phase of speed.status, ms after boot end (1): the first status, and the tick grid.
 *            A boot delay under 5 ms counts as over at reset, and a first status due before
 *            5 ms goes on the first tick from 5 ms on (the program sets the timer up before).
 *
 * Internal RAM worth a look with --dump-state (addresses as SDCC 4.2.0 places them):
 * can_restarts at 22h-23h (restarts after bus off, low byte first) and rx_lost at 24h (commands
 * dropped with the queue full; 0 on a healthy bus).
 *
 * Build (in this folder; the HEX is configs/firmware/speed_control.hex, and nothing in it may
 * be at FF00h or above, where the configuration block goes):
 *   sdcc -mmcs51 --model-small -o speed_control.ihx speed_control.c
 *   packihx speed_control.ihx > ../speed_control.hex
 */
#include "../c0/at89c51cc03.h"

/* Timer 2 counts machine cycles (1 us): 10 000 counts are 10 ms, a tick. */
#define TICK_MS 10u
#define TICK_RELOAD (65536u - 10000u)
/* Machine cycles from reset until timer 2 counts its first cycle (the reset jump, the start
 * code's stack set-up and call, and the timer writes below): loaded into the count, it makes
 * the count the machine cycles since reset until main() sets it. */
#define CYCLES_BEFORE_RUN 16u
/* Machine cycles timer2_advance() holds the timer stopped, added to the count with the rest. */
#define ADVANCE_STOPPED 7u
/* The longest period before the first tick, ms (at most 65 536 machine cycles): a boot longer
 * than twice that is counted in periods of this, the rest in two halves. */
#define LEAD_MAX_MS 65u
/* The first overflow comes no earlier: main() has set the timer up by then. */
#define EARLIEST_MS 5u

/* The kind's own constants (configs/nodes/e0.ron). */
#define STATUS_PERIOD_MS 50u
#define WATCHDOG_MS 1000u
/* The same in ticks: each is a whole number of them. */
#define STATUS_TICKS (STATUS_PERIOD_MS / TICK_MS)
#define WATCHDOG_TICKS (WATCHDOG_MS / TICK_MS)
#if STATUS_PERIOD_MS % TICK_MS || WATCHDOG_MS % TICK_MS
#error "periods must be whole ticks"
#endif

#define MESSAGE_MODE 0x01
#define DLC_MODE 2
#define MESSAGE_SETPOINT 0x02
#define DLC_SETPOINT 3
#define MESSAGE_UNLOAD 0x03
#define DLC_UNLOAD 2
#define MESSAGE_STATUS 0x10
#define DLC_STATUS 7
#define STATUS_SETPOINT_TIMEOUT 0x02 /* Data6 bit 1; bit 0, operator_override, stays 0 */
/* The largest set-point speed.status carries and the drive takes, 0.01 km/h. */
#define SETPOINT_MAX 1200u

#define STATE_MANUAL 0
#define STATE_CRUISE 1
#define STATE_UNLOADING 2

#define ACTUAL_CHANNEL 0
#define SETPOINT_CHANNEL 1
#define MODE_CHANNEL 2
/* Mode codes 102, 512, 921: the thresholds halfway between. */
#define MODE_1_FROM 307u
#define MODE_2_FROM 717u

/* Outputs. */
#define DAC_LOW P0
#define DAC_HIGH P2
__sbit __at(0xB4) MODE_REQUEST_N; /* P3.4: low = cruise requested */
__sbit __at(0xB5) UNLOAD_N;       /* P3.5: low = unload */
#define ON 0
#define OFF 1

#define RX_CHANNEL 0
#define TX_CHANNEL 1
#define CHANNELS 15

/* CANGIE.ENRX: receive interrupts of the objects CANIE enables. */
#define CANGIE_ENRX 0x20

/* The configuration block. */
#define CFG_KIND 0x45
#define CFG_LEN 18
#define CFG_KIND_AT 0x00
#define CFG_ADDRESS 0x01
#define CFG_TX_IDT 0x02
#define CFG_RX_IDT 0x06
#define CFG_RX_IDM 0x0A
#define CFG_BOOT 0x0E
#define CFG_PHASE 0x10
__code __at(0xFF00) unsigned char cfg[CFG_LEN];

/* Ticks of 10 ms since the first (the first makes it 1), counted by the timer 2 interrupt. */
volatile unsigned char ticks;
/* Times the CAN controller was restarted after bus-off. */
unsigned int can_restarts;
/* Commands dropped because the queue was full. */
unsigned char rx_lost;

/* Frames received and not yet acted on: DLC, Data0, Data1, Data2 and the tick count at arrival
 * each. The interrupt writes at rxq_head, the main loop reads at rxq_tail; RXQ_LEN - 1 frames
 * fit. */
#define RXQ_LEN 4
#define RXQ_TICK 4
static unsigned char rxq[RXQ_LEN][5];
static volatile unsigned char rxq_head;
static volatile unsigned char rxq_tail;

static unsigned char state;
/* Ticks until the watchdog fires (in cruise). */
static unsigned char watchdog_left;
static __bit setpoint_timeout;

/* The status waiting for the transmit object. */
static unsigned char tx_data[DLC_STATUS];
static __bit send_pending;
/* The transmit object holds a frame the controller has not reported sent. */
static __bit tx_busy;
/* Boot is over: set by the timer 2 interrupt at boot end. */
static volatile __bit booted;

/* What an overflow of timer 2 is: one that only counts the boot, boot end, the first tick (boot
 * end too when the phase is 0), a tick. */
#define OV_LEAD 0
#define OV_BOOT 1
#define OV_FIRST 2
#define OV_TICK 3
/* The overflow the timer heads to, and the one after it. */
static volatile unsigned char ov_next;
static volatile unsigned char ov_then;
/* The plan of the periods before the first tick: the next point to reach (boot end, then the
 * first tick), ms from the last overflow planned to it, and the phase (boot end to the first
 * tick). */
static unsigned char plan_target;
static unsigned int plan_gap;
static unsigned int phase_ms;

/* Starts timer 2 before the C start-up code clears RAM, its count the machine cycles since
 * reset (it first overflows 65.536 ms after reset, later than main() sets it), and puts every
 * output in its resting state at once. */
unsigned char _sdcc_external_startup(void)
{
    RCAP2L = 0;
    RCAP2H = 0;
    TL2 = CYCLES_BEFORE_RUN & 0xFF;
    TH2 = CYCLES_BEFORE_RUN >> 8;
    T2CON = T2CON_TR2;
    MODE_REQUEST_N = OFF;
    UNLOAD_N = OFF;
    DAC_LOW = 0;
    DAC_HIGH = 0;
    return 0;
}

/* The period after the last overflow planned, into RCAP2 (the timer loads it at that overflow):
 * toward the next point of the plan, in one period or, for more than the timer holds, in
 * several; from the first tick on, a tick. Returns what the overflow ending it is. */
static inline unsigned char plan_period(void)
{
    unsigned int p;

    if (plan_gap == 0) {
        /* The last overflow planned is the point itself. */
        if (plan_target == OV_BOOT) {
            plan_target = OV_FIRST;
            plan_gap = phase_ms;
        } else {
            RCAP2L = TICK_RELOAD & 0xFF;
            RCAP2H = TICK_RELOAD >> 8;
            return OV_TICK;
        }
    }
    p = plan_gap;
    if (p > LEAD_MAX_MS)
        p = p > 2 * LEAD_MAX_MS ? LEAD_MAX_MS : p >> 1;
    plan_gap -= p;
    /* 65536 - 1000 p, from shifts (1000 = 1024 - 16 - 8), modulo 65536. */
    p = (p << 4) + (p << 3) - (p << 10);
    RCAP2L = p & 0xFF;
    RCAP2H = p >> 8;
    return plan_gap ? OV_LEAD : plan_target;
}

void timer2_isr(void) __interrupt(5) __using(1)
{
    unsigned char k;

    TF2 = 0;
    k = ov_next;
    if (k == OV_TICK) {
        ticks++;
        return;
    }
    ov_next = ov_then;
    ov_then = plan_period();
    if (k != OV_LEAD) {
        booted = 1;
        if (k == OV_FIRST)
            ticks++;
    }
}

/* Adds k (in DPL, DPH) to timer 2's count, the timer stopped for the ADVANCE_STOPPED machine
 * cycles of the addition (MOV, ADD, MOV, MOV, ADDC, MOV, SETB: one each), so that it counts on
 * as if it had run and then counted k - ADVANCE_STOPPED cycles more. */
static void timer2_advance(unsigned int k) __naked
{
    (void)k;
    __asm
        clr     _TR2
        mov     a, _TL2
        add     a, dpl
        mov     _TL2, a
        mov     a, _TH2
        addc    a, dph
        mov     _TH2, a
        setb    _TR2
        ret
    __endasm;
}

/* Lays the overflows out from the block's boot delay and phase: the count set so that the
 * first falls where the plan's first period from reset ends, RCAP2 for the period after it. */
static void timer2_plan(unsigned int boot_ms, unsigned int phase)
{
    unsigned int first;

    phase_ms = phase;
    if (boot_ms < EARLIEST_MS) {
        booted = 1;
        first = boot_ms + phase;
        while (first < EARLIEST_MS)
            first += TICK_MS;
        plan_target = OV_FIRST;
        plan_gap = first;
    } else {
        plan_target = phase ? OV_BOOT : OV_FIRST;
        plan_gap = boot_ms;
    }
    /* The period from reset: its reload value is what the count needs now. */
    ov_next = plan_period();
    timer2_advance(((unsigned int)RCAP2H << 8 | RCAP2L) + ADVANCE_STOPPED);
    ov_then = plan_period();
}

/* A frame for the receive object: into the queue, and the object enabled again. */
void can_isr(void) __interrupt(7) __using(1)
{
    unsigned char page = CANPAGE;
    unsigned char h;

    CANPAGE = CANPAGE_CHANNEL(RX_CHANNEL); /* INDX 0, moving on after each byte */
    if (CANSTCH & CANSTCH_RXOK) {
        h = rxq_head;
        if (!booted) {
            /* Before boot end: not heard. */
        } else if (((h + 1) & (RXQ_LEN - 1)) != rxq_tail) {
            rxq[h][0] = CANCONCH & 0x0F;
            rxq[h][1] = CANMSG;
            rxq[h][2] = CANMSG;
            rxq[h][3] = CANMSG;
            rxq[h][RXQ_TICK] = ticks;
            rxq_head = (h + 1) & (RXQ_LEN - 1);
        } else {
            rx_lost++;
        }
        CANSTCH = 0;
        CANCONCH = CANCONCH_RX | CANCONCH_IDE | 8;
    }
    CANPAGE = page;
}

/* The byte an identifier's CANIDT bytes hold in ID15..8 (destination) and ID7..0 (source). */
static unsigned char id_destination(unsigned char at)
{
    return (unsigned char)((cfg[at + 1] << 5) | (cfg[at + 2] >> 3));
}

static unsigned char id_source(unsigned char at)
{
    return (unsigned char)((cfg[at + 2] << 5) | (cfg[at + 3] >> 3));
}

static unsigned int cfg_word(unsigned char at)
{
    return cfg[at] | ((unsigned int)cfg[at + 1] << 8);
}

/* The whole CAN set-up, after a general reset: used at start and after bus-off. */
static void can_setup(void)
{
    unsigned char c;

    ECAN = 0;
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

    /* Receive object: the monitor's commands to this node, as the block says. */
    CANPAGE = CANPAGE_CHANNEL(RX_CHANNEL);
    CANIDT1 = cfg[CFG_RX_IDT];
    CANIDT2 = cfg[CFG_RX_IDT + 1];
    CANIDT3 = cfg[CFG_RX_IDT + 2];
    CANIDT4 = cfg[CFG_RX_IDT + 3];
    CANIDM1 = cfg[CFG_RX_IDM];
    CANIDM2 = cfg[CFG_RX_IDM + 1];
    CANIDM3 = cfg[CFG_RX_IDM + 2];
    CANIDM4 = cfg[CFG_RX_IDM + 3];
    CANCONCH = CANCONCH_RX | CANCONCH_IDE | 8;

    /* Transmit object: speed.status's identifier, a data frame. */
    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL);
    CANIDT1 = cfg[CFG_TX_IDT];
    CANIDT2 = cfg[CFG_TX_IDT + 1];
    CANIDT3 = cfg[CFG_TX_IDT + 2];
    CANIDT4 = cfg[CFG_TX_IDT + 3] & 0xF8;

    /* An interrupt for each frame the receive object takes. */
    CANIE1 = 0;
    CANIE2 = 1 << RX_CHANNEL;
    CANGIE = CANGIE_ENRX;

    tx_busy = 0;
    CANGCON = CANGCON_ENA;
    ECAN = 1;
}

/* One conversion of ADC channel `channel`, as a 10-bit code. */
static unsigned int adc_read(unsigned char channel)
{
    ADCON = ADCON_ADEN | ADCON_ADSST | channel;
    while (!(ADCON & ADCON_ADEOC))
        ;
    ADCON = ADCON_ADEN;
    return ((unsigned int)ADDH << 2) | (ADDL & 0x03);
}

/* A speed channel in 0.01 km/h: the centre of the code's bin, less the wire's half-code
 * offset, is c x 1200/1024 = c x 75/64; rounded (halves up), (75c + 32) / 64 =
 * c + (11c + 32) / 64 (64c taken out whole), which stays within 16 bits. 0..1199. */
static unsigned int speed_centi(unsigned char channel)
{
    unsigned int c = adc_read(channel);

    return c + ((c * 11u + 32u) >> 6);
}

static unsigned char mode_read(void)
{
    unsigned int c = adc_read(MODE_CHANNEL);

    if (c < MODE_1_FROM)
        return 0;
    if (c < MODE_2_FROM)
        return 1;
    return 2;
}

/* Entering a state: the watchdog starts on entering cruise and stops outside it. */
static void enter(unsigned char s)
{
    if (s == state)
        return;
    state = s;
    watchdog_left = WATCHDOG_TICKS;
}

static void on_frame(unsigned char __data *f)
{
    switch (f[1]) {
    case MESSAGE_MODE:
        if (f[0] != DLC_MODE)
            return;
        if (f[2] == 1) {
            MODE_REQUEST_N = ON;
            setpoint_timeout = 0;
            enter(STATE_CRUISE);
        } else if (f[2] == 0) {
            MODE_REQUEST_N = OFF;
            enter(STATE_MANUAL);
        }
        break;
    case MESSAGE_SETPOINT:
        if (f[0] != DLC_SETPOINT)
            return;
        /* The drive takes 0..12 km/h, the catalogue's range, and keeps its set-point when
         * given more: so the DAC is not written then, and no code between the old set-point
         * and the refused one (the new low byte beside the old high byte) reaches it. */
        if ((f[2] | ((unsigned int)f[3] << 8)) <= SETPOINT_MAX) {
            DAC_LOW = f[2];
            DAC_HIGH = f[3];
        }
        setpoint_timeout = 0;
        if (state == STATE_CRUISE)
            watchdog_left = WATCHDOG_TICKS;
        break;
    case MESSAGE_UNLOAD:
        if (f[0] != DLC_UNLOAD)
            return;
        if (f[2] == 1) {
            UNLOAD_N = ON;
            enter(STATE_UNLOADING);
        } else if (f[2] == 0) {
            UNLOAD_N = OFF;
            MODE_REQUEST_N = OFF;
            enter(STATE_MANUAL);
        }
        break;
    default:
        break;
    }
}

/* The status as it is now, into the transmit buffer. */
static void sample_status(void)
{
    unsigned int actual = speed_centi(ACTUAL_CHANNEL);
    unsigned int setpoint = speed_centi(SETPOINT_CHANNEL);

    if (setpoint > SETPOINT_MAX)
        setpoint = SETPOINT_MAX;
    tx_data[0] = MESSAGE_STATUS;
    tx_data[1] = (unsigned char)actual;
    tx_data[2] = (unsigned char)(actual >> 8);
    tx_data[3] = (unsigned char)setpoint;
    tx_data[4] = (unsigned char)(setpoint >> 8);
    tx_data[5] = mode_read();
    tx_data[6] = setpoint_timeout ? STATUS_SETPOINT_TIMEOUT : 0;
    send_pending = 1;
}

static void send_frame(void)
{
    unsigned char i;

    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL); /* INDX 0, moving on after each byte */
    for (i = 0; i < DLC_STATUS; i++)
        CANMSG = tx_data[i];
    CANSTCH = 0;
    CANCONCH = CANCONCH_TX | CANCONCH_IDE | DLC_STATUS;
    tx_busy = 1;
    send_pending = 0;
}

/* A frame sent frees the transmit object. */
static void can_service(void)
{
    if (tx_busy) {
        CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL);
        if (CANSTCH & CANSTCH_TXOK) {
            CANSTCH = 0;
            tx_busy = 0;
        }
    }
}

/* The watchdog, once a tick in cruise. */
static void run_watchdog(void)
{
    if (state == STATE_CRUISE && --watchdog_left == 0) {
        MODE_REQUEST_N = OFF;
        setpoint_timeout = 1;
        state = STATE_MANUAL;
    }
}

static __bit config_ok(void)
{
    unsigned char address = cfg[CFG_ADDRESS];

    return cfg[CFG_KIND_AT] == CFG_KIND && id_source(CFG_TX_IDT) == address &&
           id_destination(CFG_RX_IDT) == address;
}

void main(void)
{
    unsigned char seen = 0;
    unsigned char now;
    unsigned char status_left = 1;

    if (!config_ok()) {
        /* No block for this firmware: stay off the bus, the outputs off. */
        T2CON = 0;
        for (;;)
            ;
    }
    state = STATE_MANUAL;

    /* P1.0-P1.2 are analog inputs. */
    ADCF = (1 << ACTUAL_CHANNEL) | (1 << SETPOINT_CHANNEL) | (1 << MODE_CHANNEL);
    ADCLK = 0x03; /* ADC clock 6 MHz / (4 x 3) = 500 kHz */
    ADCON = ADCON_ADEN;
    can_setup();
    timer2_plan(cfg_word(CFG_BOOT), cfg_word(CFG_PHASE));
    ET2 = 1;
    EA = 1;

    for (;;) {
        if (CANGSTA & CANGSTA_BOFF) {
            /* A frame lost with the controller goes out again after the restart. */
            if (tx_busy)
                send_pending = 1;
            can_setup();
            can_restarts++;
        }
        /* Commands and ticks in the order they came. With the ticks counted so far read
         * first, the commands that came before the next tick to handle (stamped seen) are acted
         * on at once; one that came after it waits until it is handled, and a command or a tick
         * that comes after the read, until the next turn. Every frame queued came at tick seen
         * or later. */
        now = ticks;
        while (rxq_tail != rxq_head && rxq[rxq_tail][RXQ_TICK] == seen) {
            on_frame(rxq[rxq_tail]);
            rxq_tail = (rxq_tail + 1) & (RXQ_LEN - 1);
        }
        if (send_pending) {
            /* A status waits for the object (or a restart lost the last): out once it is free. */
            can_service();
            if (!tx_busy)
                send_frame();
        }
        if (seen != now) {
            seen++;
            can_service();
            if (--status_left == 0) {
                status_left = STATUS_TICKS;
                sample_status();
                if (!tx_busy)
                    send_frame();
            }
            run_watchdog();
        }
    }
}
