; irq_receiver.asm: a receiver that takes frames in its INT0 interrupt, for the seed lab's sender
; (can_seed.asm on the sending bench). An 80C51 at 12 MHz with one SJA1000 at D400H (6 MHz
; crystal, 30 kbit/s as in the lab), its INT output wired to INT0 (P3.2). The main loop does
; nothing (SJMP to itself): the INT0 handler copies each frame's eight data bytes to internal RAM
; 30H-37H, releases the receive buffer and counts frames in R5 (register bank 0).
;
; Rebuild the HEX, in this folder:
;     as31 -Fhex -Oirq_receiver.hex irq_receiver.asm
;
; Bit addresses: TCON.0 (IT0) is 88H, IE.0 (EX0) A8H, IE.7 (EA) AFH.
        .org    0000H
        LJMP    START
        .org    0003H
        LJMP    ISR0
        .org    0030H
START:  MOV     SP, #60H
        MOV     DPTR, #0D400H
        MOV     A, #09H         ; MOD: reset mode (BasicCAN CR first, as in the lab)
        MOVX    @DPTR, A
        MOV     DPL, #1FH       ; CDR: PeliCAN
        MOV     A, #88H
        MOVX    @DPTR, A
        MOV     DPL, #04H       ; IER: receive interrupt only
        MOV     A, #01H
        MOVX    @DPTR, A
        MOV     DPL, #06H       ; BTR0, BTR1: 30 kbit/s at 6 MHz
        MOV     A, #03H
        MOVX    @DPTR, A
        INC     DPTR
        MOV     A, #0FFH
        MOVX    @DPTR, A
        MOV     DPL, #10H       ; ACR0 BBh, ACR1-3 FFh, AMR0 00h, AMR1-3 FFh
        MOV     A, #0BBH
        MOVX    @DPTR, A
        MOV     A, #0FFH
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        CLR     A
        MOVX    @DPTR, A
        MOV     A, #0FFH
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        MOV     DPL, #00H       ; MOD: operating mode, single filter
        MOV     A, #08H
        MOVX    @DPTR, A
        MOV     R5, #00H
        CLR     88H             ; IT0 = 0: INT0 level-triggered (SETB 88H: falling edge)
        SETB    0A8H            ; EX0
        SETB    0AFH            ; EA
IDLE:   SJMP    IDLE
ISR0:   PUSH    ACC
        PUSH    DPL
        PUSH    DPH
        MOV     DPTR, #0D403H   ; IR: reading it clears all but RI
        MOVX    A, @DPTR
        MOV     DPTR, #0D413H   ; first data byte of a standard frame
        MOV     R0, #30H
        MOV     R2, #08H
COPY:   MOVX    A, @DPTR
        MOV     @R0, A
        INC     R0
        INC     DPTR
        DJNZ    R2, COPY
        MOV     DPTR, #0D401H   ; CMR: release the receive buffer
        MOV     A, #04H
        MOVX    @DPTR, A
        INC     R5
        POP     DPH
        POP     DPL
        POP     ACC
        RETI
