/*
 * alarm_module.c: the alarm module CanModuleC (C0-C3) as AT89C51CC03 firmware.
 *
 * One image for all four modules; it generalises c0/c0_alarm.c (C0 alone, its settings in the
 * code) to every alarm module. What makes a module C0 or C3 (its identifiers, its message, its
 * timing, which switch goes to which bit and how the analog input is scaled and quantized) is
 * the CONFIGURATION BLOCK at FF00h in code memory, which the node file supplies
 * (`config: (at: 0xFF00, bytes: [...])`); this source only declares it. It behaves as the
 * script template configs/nodes/templates/alarm_module.ron: from its boot delay on it builds
 * its frame from the inputs at every check (every 10 ms) and sends it when its content differs
 * from the last one sent, or when the heartbeat (1000 ms) has passed since that send. The
 * heartbeat restarts with every frame sent, whatever made it go. The analog input is quantized
 * to the step the block gives, so that noise does not count as a change.
 *
 * Hardware, as the firmware node files wire it:
 *   - 12 MHz crystal, X1 mode: a machine cycle is 1 us; F_CAN = 6 MHz.
 *   - Alarm switches on port pins (C0-C3: P2.0 up, pin high = on).
 *   - The analog sensor on an ADC channel (C0-C3: channel 0, P1.0), VAREF = 5000 mV. The node
 *     file's `analog` wire puts the field's catalogue range on 0..5000 mV (pin mV = offset_mv +
 *     signal x scale); the block says how to turn a 10-bit code back into the field's value.
 *   - CAN at 250 kbit/s on the on-chip controller (TxDC/RxDC).
 *
 * Timing: timer 2 in auto-reload mode interrupts every 10 ms (10 000 machine cycles, RCAP2 =
 * 65536 - 10000), as in c0_alarm.c; since boot delays such as C1's 65 ms are not multiples of
 * 10, the grid of ticks is laid on the node's own schedule. From reset timer 2 counts
 * microseconds (it starts in the 16th machine cycle with the count 16, so that it would first
 * overflow 65.536 ms after reset). main reads the first check's moment F = boot delay from the
 * block and, timer 2 held still for ALIGN_STOPPED cycles, adds to its count what makes it
 * overflow first at L = 10 + (F - 10) mod 10 ms after reset (10-19 ms, long after main has got
 * there) and every 10 ms from then on: F is then tick (F - L) / 10 + 1 exactly, e.g. C1
 * (F = 65 ms) ticks at 15, 25, ... ms and checks first at its 6th tick. The check period is a
 * whole number of ticks (one for C0-C3), so every check falls on a tick. (A block whose F is
 * under 10 ms has its first check 10 ms after reset.) The main loop handles every tick: it
 * frees the transmit channel when its frame has gone, counts down to the next check, checks and
 * hands a frame to the controller. Between ticks it polls CANGSTA.BOFF; after bus off it
 * restarts the controller (general reset, then the whole set-up again), counts the restart in
 * can_restarts and sends again, at the next tick, the frame the controller lost. A frame decided
 * while the previous one is still waiting for the bus goes as soon as the channel is free: the
 * loop between ticks watches for it then (the newest decision wins).
 *
 * CONFIGURATION BLOCK at FF00h (all 16-bit values little-endian):
 *   +00      43h ('C'): an alarm module block. Anything else (an erased FFh, the parameter
 *            module's 42h) and the firmware never starts its CAN controller: the node is
 *            silent and the monitor reports it so.
 *   +01      the node's address (C0h-C3h): not used by the code (the identifiers are given in
 *            full below), there so that a dump of code memory says whose block it is.
 *   +02..05  CANIDT1-4 of the transmit object: the frame's 29-bit identifier shifted left by 3
 *            (RTRTAG 0: a data frame), e.g. 0400F5C0 -> 20 07 AE 00.
 *   +06..09  CANIDT1-4 of the receive object: the identifier the monitor would address the node
 *            with (0400xxF5) shifted left by 3. The node takes no message; the object only makes
 *            its acceptance filter the one the script declares.
 *   +0A..0D  CANIDM1-4 of the receive object (FF FF FF FD: every identifier bit, RTRMSK and
 *            IDEMSK compared).
 *   +0E      Data0: the catalogue message number.
 *   +0F      DLC, 1-8.
 *   +10..11  boot delay, ms from reset: the first check; the tick grid is laid so that a tick
 *            falls there (see Timing).
 *   +12..13  check period, ms: a multiple of 10 (a whole number of ticks), 10-65530.
 *   +14..15  heartbeat, ms (1-65535): a frame goes at the first check at least this long after
 *            the last one sent.
 *   +16      NA: number of analog fields (0-4).
 *   +17      NP: number of pin fields (0-16).
 *   +18      NA analog field descriptors of 10 bytes, then NP pin field descriptors of 4 bytes.
 *
 *   Analog field descriptor (10 bytes):
 *   +0       ADC channel, 0-7 (pin P1.channel).
 *   +1       data byte of its low byte, 1-7.
 *   +2       width in bytes: 1 or 2 (little-endian; the value's low byte(s) are sent).
 *   +3       SHIFT, 0-24.
 *   +4..5    MUL.
 *   +6..7    STEP: the quantization step, in the field's raw units.
 *   +8..9    BIAS.
 *            The code c (0-1023) stands for the pin voltage at the centre of its bin,
 *            (c + 1/2) x 5000 / 1024 mV. The firmware computes
 *                n     = ((2c + 1) x MUL + 2^(SHIFT-1)) >> SHIFT     (32-bit; no rounding term
 *                                                                      when SHIFT is 0)
 *                value = n x STEP - BIAS                             (16-bit, modulo 2^16)
 *            A wire that puts the field's raw range [0, hi] on 0..5000 mV (scale = 5000 / hi mV
 *            per raw unit) has (c + 1/2) x hi / 1024 raw units at the bin's centre, which is
 *            n = that / STEP rounded to the nearest whole step: MUL = hi / STEP, SHIFT = 11,
 *            BIAS = 0. C0: hi 5000 mV, STEP 100 mV, MUL 50, the same n as c0_alarm.c's
 *            ((2c + 1) x 25 + 512) >> 10. C3: hi 32000 mV, STEP 200, MUL 160. A bin's centre
 *            falls exactly on a half step only when MUL is an odd multiple of 2^(SHIFT-1)
 *            (never with these blocks); it would round up, as the script's Quantize rounds a
 *            half away from zero.
 *
 *   Pin field descriptor (4 bytes):
 *   +0       port 0-3 in bits 1-0; bit 7 set: active low (the data bit is 1 while the pin is
 *            low).
 *   +1       pin, 0-7.
 *   +2       data byte, 1-7.
 *   +3       data bit, 0-7: set while the pin is high (low, if active low).
 *
 *   A block that breaks these rules (a DLC of 0 or above 8, a check period of 0 or not a
 *   multiple of 10 ms, a heartbeat of 0, more than 4 analog or 16 pin fields, a field outside
 *   the DLC, a channel, port, bit or SHIFT out of range) is refused as a missing one: the node
 *   stops timer 2 and stays silent.
 *
 * Build (in this folder; the HEX is configs/firmware/alarm_module.hex):
 *   sdcc -mmcs51 --model-small -o alarm_module.ihx alarm_module.c
 *   packihx alarm_module.ihx > ../alarm_module.hex
 * The image must write nothing at FF00h or above: the node file's block goes there.
 */
#include "../c0/at89c51cc03.h"

/* Timer 2 counts machine cycles (1 us): a tick is 10 000 counts, 10 ms. */
#define TICK_MS 10u
#define TICK_RELOAD (65536u - 10000u)
/* Machine cycles from reset until timer 2 counts its first cycle (the reset jump, the start
 * code's stack set-up and call, and the writes below): timer 2 starts with this count, so that
 * until align_ticks its count is the microseconds since reset. */
#define CYCLES_BEFORE_RUN 16u
/* Machine cycles timer 2 misses while align_ticks holds it still: from its CLR TR2 to its
 * SETB TR2, seven one-cycle instructions. */
#define ALIGN_STOPPED 7u

#define RX_CHANNEL 0
#define TX_CHANNEL 1
#define CHANNELS 15

/* The configuration block: the node file writes it; the image leaves these bytes alone. */
#define CFG_SIZE 256
__code __at(0xFF00) unsigned char cfg[CFG_SIZE];

#define CFG_MAGIC 0x00
#define CFG_ADDRESS 0x01
#define CFG_TX_IDT 0x02
#define CFG_RX_IDT 0x06
#define CFG_RX_IDM 0x0A
#define CFG_DATA0 0x0E
#define CFG_DLC 0x0F
#define CFG_BOOT 0x10
#define CFG_CHECK 0x12
#define CFG_HEARTBEAT 0x14
#define CFG_NA 0x16
#define CFG_NP 0x17
#define CFG_FIELDS 0x18

#define MAGIC_ALARM 0x43

#define ANALOG_SIZE 10
#define A_CHANNEL 0
#define A_BYTE 1
#define A_WIDTH 2
#define A_SHIFT 3
#define A_MUL 4
#define A_STEP 6
#define A_BIAS 8

#define PIN_SIZE 4
#define P_PORT 0
#define P_PIN 1
#define P_BYTE 2
#define P_BIT 3
#define P_ACTIVE_LOW 0x80

#define MAX_ANALOG 4
#define MAX_PINS 16
#define MAX_SHIFT 24

/* The fields as the block describes them, unpacked once at start into internal RAM, so that
 * sampling costs a fraction of a millisecond. */
struct analog_field {
    unsigned char channel; /* ADC channel */
    unsigned char at;      /* data byte of the low byte */
    unsigned char width;   /* 1 or 2 bytes */
    unsigned char shift;
    unsigned int mul;
    unsigned int step;
    unsigned int bias;
};

struct pin_field {
    unsigned char port;   /* 0-3 */
    unsigned char mask;   /* the pin's bit in the port */
    unsigned char invert; /* 00h, or FFh for an active-low pin */
    unsigned char at;     /* data byte */
    unsigned char bit;    /* the bit in it */
};

static __idata struct analog_field analog[MAX_ANALOG];
static __idata struct pin_field pin[MAX_PINS];

/* What the fields read last: the ports and the pin fields' bits in each data byte, each analog
 * field's code and value. A port or a code that has not changed since is not worked out again:
 * most checks find the machine as it was. */
static __idata unsigned char last_ports[4];
static __idata unsigned char pin_bits[8];
static __bit pins_known;
static __idata unsigned int last_code[MAX_ANALOG];
static __idata unsigned int last_value[MAX_ANALOG];
static __idata unsigned char value_known;

/* Ticks of 10 ms (modulo 256), counted by the timer 2 interrupt. */
volatile unsigned char ticks;
/* Times the CAN controller was restarted after bus-off. */
unsigned int can_restarts;

/* The block's settings, read once at start. */
static unsigned char dlc;
static unsigned char analog_fields;
static unsigned char pin_fields;
static unsigned int check_ms;
static unsigned int check_ticks;
static unsigned int heartbeat_ms;

/* Ticks until the next check. */
static unsigned int due;
/* The frame the inputs make now, and the content of the last frame sent: Data0-Data7. */
static unsigned char frame[8];
static unsigned char sent[8];
static __bit sent_any;
/* Milliseconds since the last frame was sent, counted at the checks (up to the heartbeat). */
static unsigned int since_sent;
/* A frame is decided but not yet handed to the controller (the last one is still on its way). */
static __bit send_pending;
/* Channel TX_CHANNEL holds a frame the controller has not reported sent. */
static __bit tx_busy;

/* Starts timer 2 before the C start-up code clears RAM, so that it counts from reset: its count
 * is the microseconds since reset until align_ticks moves it. */
unsigned char _sdcc_external_startup(void)
{
    RCAP2L = TICK_RELOAD & 0xFF;
    RCAP2H = TICK_RELOAD >> 8;
    TL2 = CYCLES_BEFORE_RUN & 0xFF;
    TH2 = CYCLES_BEFORE_RUN >> 8;
    T2CON = T2CON_TR2;
    return 0;
}

void timer2_isr(void) __interrupt(5)
{
    TF2 = 0;
    ticks++;
}

static unsigned int cfg16(unsigned char at)
{
    return cfg[at] | ((unsigned int)cfg[at + 1] << 8);
}

/* What align_ticks adds to timer 2's count (for its inline assembly): 65536 - the first
 * overflow's time in us + ALIGN_STOPPED, modulo 2^16. */
unsigned int align_add;

/* Lays the tick grid on the node's schedule, its first event first_ms after reset: timer 2, still
 * counting microseconds since reset (far from the 10 ms this is called before), is held still
 * for ALIGN_STOPPED cycles and moved so that it overflows first at lead = 10 + (first_ms - 10)
 * mod 10 ms, then every 10 ms. Returns the number of the tick at first_ms (tick 1 at lead). */
static unsigned int align_ticks(unsigned int first_ms)
{
    unsigned char lead_ms = TICK_MS;
    unsigned int tick = 1;

    if (first_ms >= TICK_MS) {
        lead_ms = TICK_MS + (unsigned char)((first_ms - TICK_MS) % TICK_MS);
        tick = (first_ms - lead_ms) / TICK_MS + 1;
    }
    align_add = ALIGN_STOPPED - lead_ms * 1000u;
    /* A fixed number of cycles with the timer stopped: count += align_add. */
    __asm
        clr     _TR2
        mov     a,_TL2
        add     a,_align_add
        mov     _TL2,a
        mov     a,_TH2
        addc    a,(_align_add + 1)
        mov     _TH2,a
        setb    _TR2
    __endasm;
    return tick;
}

/* ADCF for the analog channels the block uses, set by config_ok. */
static unsigned char adcf;

/* Whether the block is one this firmware can run; reads its settings and unpacks its fields. */
static __bit config_ok(void)
{
    unsigned char k, d, v;

    if (cfg[CFG_MAGIC] != MAGIC_ALARM)
        return 0;
    dlc = cfg[CFG_DLC];
    analog_fields = cfg[CFG_NA];
    pin_fields = cfg[CFG_NP];
    check_ms = cfg16(CFG_CHECK);
    heartbeat_ms = cfg16(CFG_HEARTBEAT);
    if (dlc == 0 || dlc > 8 || check_ms == 0 || check_ms % TICK_MS || heartbeat_ms == 0 ||
        analog_fields > MAX_ANALOG || pin_fields > MAX_PINS)
        return 0;
    check_ticks = check_ms / TICK_MS;
    if (CFG_FIELDS + analog_fields * ANALOG_SIZE + pin_fields * PIN_SIZE > CFG_SIZE)
        return 0;
    adcf = 0;
    d = CFG_FIELDS;
    for (k = 0; k < analog_fields; k++, d += ANALOG_SIZE) {
        __idata struct analog_field *a = &analog[k];
        a->channel = cfg[d + A_CHANNEL];
        a->at = cfg[d + A_BYTE];
        a->width = cfg[d + A_WIDTH];
        a->shift = cfg[d + A_SHIFT];
        a->mul = cfg16(d + A_MUL);
        a->step = cfg16(d + A_STEP);
        a->bias = cfg16(d + A_BIAS);
        if (a->channel > 7 || a->shift > MAX_SHIFT || a->width == 0 || a->width > 2)
            return 0;
        if (a->at == 0 || a->at + a->width > dlc)
            return 0;
        adcf |= 1 << a->channel;
    }
    for (k = 0; k < pin_fields; k++, d += PIN_SIZE) {
        __idata struct pin_field *p = &pin[k];
        v = cfg[d + P_PORT];
        if ((v & ~(P_ACTIVE_LOW | 3)) || cfg[d + P_PIN] > 7 || cfg[d + P_BIT] > 7)
            return 0;
        p->port = v & 3;
        p->invert = (v & P_ACTIVE_LOW) ? 0xFF : 0x00;
        p->mask = 1 << cfg[d + P_PIN];
        p->at = cfg[d + P_BYTE];
        p->bit = 1 << cfg[d + P_BIT];
        if (p->at == 0 || p->at >= dlc)
            return 0;
    }
    return 1;
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

    /* Channel 0 receives what the monitor would address to the node, nothing else. */
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

    /* Channel 1 sends: the frame's identifier << 3, a data frame (RTRTAG 0). */
    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL);
    CANIDT1 = cfg[CFG_TX_IDT];
    CANIDT2 = cfg[CFG_TX_IDT + 1];
    CANIDT3 = cfg[CFG_TX_IDT + 2];
    CANIDT4 = cfg[CFG_TX_IDT + 3];

    tx_busy = 0;
    CANGCON = CANGCON_ENA;
}

/* One conversion of an ADC channel, as a 10-bit code. */
static unsigned int adc_read(unsigned char channel)
{
    ADCON = ADCON_ADEN | ADCON_ADSST | (channel & ADCON_SCH);
    while (!(ADCON & ADCON_ADEOC))
        ;
    ADCON = ADCON_ADEN;
    return ((unsigned int)ADDH << 2) | (ADDL & 0x03);
}

/* An analog field: its channel converted, the code taken at the centre of its bin and scaled
 * as the block says. (x + 2^(s-1)) >> s is computed as ((x >> (s-1)) + 1) >> 1, the same. */
static unsigned int analog_value(unsigned char k)
{
    __idata struct analog_field *a = &analog[k];
    unsigned int code = adc_read(a->channel);
    unsigned char shift = a->shift;
    unsigned long x;

    if ((value_known & (1 << k)) && code == last_code[k])
        return last_value[k];
    x = (unsigned long)((code << 1) + 1) * a->mul;

    if (shift) {
        shift--;
        while (shift >= 8) {
            x >>= 8;
            shift -= 8;
        }
        x >>= shift;
        x = (x + 1) >> 1;
    }
    last_code[k] = code;
    last_value[k] = (unsigned int)x * a->step - a->bias;
    value_known |= 1 << k;
    return last_value[k];
}

/* The pin fields' bits in each data byte, from the ports as they read now. */
static void pin_sample(unsigned char p0, unsigned char p1, unsigned char p2, unsigned char p3)
{
    unsigned char k;
    __idata unsigned char ports[4];

    ports[0] = last_ports[0] = p0;
    ports[1] = last_ports[1] = p1;
    ports[2] = last_ports[2] = p2;
    ports[3] = last_ports[3] = p3;
    for (k = 0; k < 8; k++)
        pin_bits[k] = 0;
    for (k = 0; k < pin_fields; k++) {
        __idata struct pin_field *p = &pin[k];
        if ((ports[p->port] ^ p->invert) & p->mask)
            pin_bits[p->at] |= p->bit;
    }
    pins_known = 1;
}

/* Reads every field into frame[]: the ports once (the pin fields worked out again only when one
 * changed), then each analog field, the pin bits of its bytes kept. */
static void sample(void)
{
    unsigned char k;
    unsigned int value;
    unsigned char p0 = P0, p1 = P1, p2 = P2, p3 = P3;

    if (!pins_known || p0 != last_ports[0] || p1 != last_ports[1] || p2 != last_ports[2] ||
        p3 != last_ports[3])
        pin_sample(p0, p1, p2, p3);
    frame[0] = cfg[CFG_DATA0];
    frame[1] = pin_bits[1];
    frame[2] = pin_bits[2];
    frame[3] = pin_bits[3];
    frame[4] = pin_bits[4];
    frame[5] = pin_bits[5];
    frame[6] = pin_bits[6];
    frame[7] = pin_bits[7];
    for (k = 0; k < analog_fields; k++) {
        __idata struct analog_field *a = &analog[k];
        unsigned char at = a->at;
        value = analog_value(k);
        frame[at] = (value & 0xFF) | pin_bits[at];
        if (a->width == 2)
            frame[at + 1] = (value >> 8) | pin_bits[at + 1];
    }
}

static void send_frame(void)
{
    unsigned char k;

    CANPAGE = CANPAGE_CHANNEL(TX_CHANNEL); /* INDX 0, moving on after each byte */
    for (k = 0; k < dlc; k++)
        CANMSG = sent[k];
    CANSTCH = 0;
    CANCONCH = CANCONCH_TX | CANCONCH_IDE | dlc;
    tx_busy = 1;
    send_pending = 0;
}

/* What the script does at each check: sample, compare with the last frame sent, send on a
 * change or when the heartbeat is due. */
static void check(void)
{
    unsigned char k;
    __bit changed = !sent_any;

    sample();
    for (k = 0; k < dlc; k++)
        if (frame[k] != sent[k])
            changed = 1;
    if (since_sent < heartbeat_ms)
        since_sent += check_ms;
    if (changed || since_sent >= heartbeat_ms) {
        for (k = 0; k < dlc; k++)
            sent[k] = frame[k];
        sent_any = 1;
        since_sent = 0;
        send_pending = 1;
    }
}

/* Channel housekeeping at every tick, and between ticks while a frame waits for the channel: a
 * frame sent frees the transmit channel; a frame received (the node takes none) re-arms the
 * receive channel. */
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

    /* The tick grid first, while timer 2 still counts from reset; then count every tick. */
    due = align_ticks(cfg16(CFG_BOOT));
    ET2 = 1;
    EA = 1;
    if (!config_ok()) {
        /* No block, or not an alarm module's: stay off the bus, timer 2 stopped. */
        EA = 0;
        T2CON = 0;
        for (;;)
            ;
    }

    ADCF = adcf;  /* the P1 pins of the analog fields are analog inputs */
    ADCLK = 0x03; /* ADC clock 6 MHz / (4 x 3) = 500 kHz */
    ADCON = ADCON_ADEN;
    can_setup();

    for (;;) {
        while (seen == ticks) {
            if (CANGSTA & CANGSTA_BOFF) {
                /* A frame lost with the controller goes out again after the restart. */
                if (tx_busy)
                    send_pending = 1;
                can_setup();
                can_restarts++;
            } else if (send_pending && tx_busy) {
                /* A frame waits behind one the controller still holds: it goes as soon as the
                 * channel is free, not at the next tick. */
                can_service();
                if (!tx_busy)
                    send_frame();
            }
        }
        seen++;
        can_service();
        if (due)
            due--;
        if (!due) {
            due = check_ticks;
            check();
        }
        if (send_pending && !tx_busy)
            send_frame();
    }
}
