; can_seed.asm: CAN.ASM from a university lab report on CAN communication with an 80C51 and an
; SJA1000 (CAN.ASM), converted to the syntax of the as31 assembler (Debian package as31).
; The lab: two benches, each an 80C51 at 12 MHz with one SJA1000 (6 MHz crystal) and a
; PCA82C250 transceiver, joined by one CAN bus. See README.md beside this file.
;
; Rebuild the HEX, in this folder:
;     as31 -Fhex -Ocan_seed.hex can_seed.asm
;
; Every change made to the report's listing, one a line:
; - "NAME EQU value" is written ".equ NAME, value" (as31 knows only the dotted form).
; - "ORG" is written ".org" (as31 knows only the dotted form).
; - "DB" is written ".byte" (as31 has no DB).
; - "JMP START" (generic jump) is "LJMP START": as31 has no generic JMP/CALL, only JMP @A+DPTR.
; - "HALT: JMP LOOP" (generic jump) is "HALT: LJMP LOOP", for the same reason.
; - The register name MOD is kept: it is no keyword of as31, which takes it as a symbol.
; - The comments are translated from Chinese into English; a few notes (marked "Note:") are added.
; - The end of the receive routine (the copy loop RDATA1, the receive buffer release and the
;   label RECOUT with its RET) is completed: the report's listing stops after "MOV R2,#08H".
; - The DELAY subroutine is written anew: the report calls it but does not show it.
; Nothing else is changed: the labels, the instructions and their order are the report's.
;
; The same image runs on both benches. Each board has one SJA1000: the sending bench's at
; D300H (chip select LCS2), the receiving bench's at D400H (LCS3); the other address decodes
; nothing, so a read there gives FFH and a write there is lost. What each bench does:
; - Sending bench: INITCAN at D3H sets up its chip (acceptance code AAH); INITCAN at D4H writes
;   into nothing. In LOOP, SEND at D3H loads the frame (ID 5DFH, 8 bytes) and requests its
;   transmission; DELAY waits about 100 ms; RECV at D4H reads SR = FFH, so SR AND C3H = C3H is
;   not zero and bit 7 (bus status) is set: it takes the bus-off path BUSERR, reads IR (FFH)
;   and writes MOD = 08H into nothing, and returns. Its 30H-37H are never written.
; - Receiving bench: INITCAN at D3H writes into nothing; INITCAN at D4H sets up its chip
;   (acceptance code BBH). In LOOP, SEND at D3H writes into nothing, so it never transmits;
;   RECV at D4H returns at once while SR shows nothing; once the frame from the sending bench
;   is in its receive buffer (SR bit 0, IR bit 0), RECV copies the 8 data bytes to 30H-37H and
;   releases the buffer (CMR = 04H). 30H-37H then hold AA BB CC D4 E5 F6 97 18.

.equ MOD, 00H           ; mode register
.equ CMR, 01H           ; command register
.equ SR, 02H            ; status register
.equ IR, 03H            ; interrupt register
.equ IER, 04H           ; interrupt enable register
.equ BTR0, 06H          ; bus timing register 0
.equ BTR1, 07H          ; bus timing register 1
.equ OCR, 08H           ; output control register
.equ ALC, 0BH           ; arbitration lost capture register
.equ ECC, 0CH           ; error code capture register
.equ TXERR, 0FH         ; transmit error counter
.equ ACR0, 10H          ; acceptance code register 0
.equ ACR1, 11H          ; acceptance code register 1
.equ ACR2, 12H          ; acceptance code register 2
.equ ACR3, 13H          ; acceptance code register 3
.equ AMR0, 14H          ; acceptance mask register 0
.equ AMR1, 15H          ; acceptance mask register 1
.equ AMR2, 16H          ; acceptance mask register 2
.equ AMR3, 17H          ; acceptance mask register 3
.equ FIN, 10H           ; transmit/receive frame information
.equ ID1, 11H           ; transmit/receive buffer: identifier byte 1
.equ ID2, 12H           ; transmit/receive buffer: identifier byte 2
.equ DATA1, 13H         ; transmit/receive buffer: first data byte
.equ RBSA, 1EH          ; receive buffer start address
.equ CDR, 1FH           ; clock divider register

;----- READER COS 1.0 -----
        .org    4000H
        LJMP    START
        .org    4080H

;----- main program -----
START:  MOV     DPH, #0D3H      ; initialise CAN1 (CAN1 chip select is
                                ; LCS2: 0D300H)
        MOV     R0, #0AAH       ; acceptance code AAH
        LCALL   INITCAN
        MOV     DPH, #0D4H      ; initialise CAN2 (CAN2 chip select is
                                ; LCS3: 0D400H)
        MOV     R0, #0BBH       ; acceptance code BBH
        LCALL   INITCAN

;-----
        MOV     R0, #20H        ; fill 20H-27H with the data to send
        MOV     R1, #00H
        MOV     DPTR, #TXDATA
SS1:    MOV     A, R1
        MOVC    A, @A+DPTR
        MOV     @R0, A
        INC     R0
        INC     R1
        CJNE    R1, #08, SS1

;----- CAN1 sends one frame -----
LOOP:   MOV     DPH, #0D3H
        MOV     R0, #20H
        LCALL   SEND            ; send one frame of the data at 20H (the three
                                ; control bytes 08H, BBH, FFH are set by SEND)
        LCALL   DELAY           ; call the delay subroutine

;----- CAN2 receives one frame -----
        MOV     DPH, #0D4H
        MOV     R0, #30H
        LCALL   RECV            ; call the receive subroutine
        NOP                     ; breakpoint here
HALT:   LJMP    LOOP

TXDATA: .byte   0AAH, 0BBH, 0CCH, 0D4H  ; the frame's data, the user may change it
        .byte   0E5H, 0F6H, 97H, 18H

;----- initialisation subroutine -----
INITCAN:                        ; DPH, R0 are the input parameters
        MOV     DPL, #MOD       ; mode register: single acceptance filter,
        MOV     A, #09H         ; enter reset mode
        MOVX    @DPTR, A
        MOV     DPL, #CDR       ; clock divider: PeliCAN mode,
        MOV     A, #88H         ; CLKOUT off
        MOVX    @DPTR, A
        MOV     DPL, #IER       ; interrupt enable: overrun, error,
        MOV     A, #0DH         ; receive interrupts
        MOVX    @DPTR, A
        MOV     DPL, #BTR0      ; bus timing register 0
        MOV     A, #03H
        MOVX    @DPTR, A
        MOV     DPL, #BTR1      ; bus timing register 1: 6 MHz crystal,
        MOV     A, #0FFH        ; 30 kbit/s
        MOVX    @DPTR, A
        MOVX    A, @DPTR        ; Note: reads BTR1 back; A is overwritten below
        MOV     DPL, #OCR       ; output control register:
                                ; normal output mode
        MOV     A, #0AAH
        MOVX    @DPTR, A
        MOV     DPL, #ACR0      ; acceptance code register ACR0
        MOV     A, R0
        MOVX    @DPTR, A
        INC     DPTR            ; acceptance code register ACR1
        MOV     A, #0FFH
        MOVX    @DPTR, A
        INC     DPTR            ; acceptance code register ACR2
        MOVX    @DPTR, A
        INC     DPTR            ; acceptance code register ACR3
        MOVX    @DPTR, A
        MOV     DPL, #AMR0      ; acceptance mask register AMR0
        MOV     A, #00H
        MOVX    @DPTR, A
        INC     DPTR            ; acceptance mask register AMR1
        MOV     A, #0FFH
        MOVX    @DPTR, A
        INC     DPTR            ; acceptance mask register AMR2
        MOVX    @DPTR, A
        INC     DPTR            ; acceptance mask register AMR3
        MOVX    @DPTR, A
        MOV     DPL, #RBSA      ; receive buffer start address 0
        MOV     A, #00H
        MOVX    @DPTR, A
        MOV     DPL, #TXERR     ; clear the transmit error counter
        MOVX    @DPTR, A
        MOV     DPL, #ECC       ; clear the error code capture register
        MOVX    @DPTR, A        ; Note: ECC is read-only in the SJA1000: no effect
        MOV     DPL, #MOD       ; single acceptance filter, back to operating mode
        MOV     A, #08H
        MOVX    @DPTR, A
        RET

;----- send subroutine -----
SEND:                           ; DPH, R0 are the input parameters
        MOV     DPL, #FIN       ; start of the SJA1000 transmit buffer
        MOV     A, #08H
        MOVX    @DPTR, A
        INC     DPL
        MOV     A, #0BBH
        MOVX    @DPTR, A
        INC     DPL
        MOV     A, #0FFH
        MOVX    @DPTR, A
        INC     DPL
        MOV     R2, #08H
SEND1:  MOV     A, @R0          ; R0 points at the data to send
        MOVX    @DPTR, A
        INC     R0
        INC     DPL
        DJNZ    R2, SEND1
        MOV     DPL, #CMR       ; command register: transmission request,
        MOV     A, #01H         ; the SJA1000 starts sending
        MOVX    @DPTR, A
        RET

;----- receive subroutine -----
RECV:                           ; DPH, R0 are the input parameters
        MOV     DPL, #SR        ; status register address
        MOVX    A, @DPTR
        ANL     A, #0C3H        ; keep the bus-off, error, data overrun
                                ; and receive buffer status bits
        JNZ     PROC
        RET                     ; none of them: done
PROC:   JNB     ACC.7, PROC1
BUSERR: MOV     DPL, #IR        ; interrupt register: bus off
        MOVX    A, @DPTR        ; read the interrupt register, clearing its bits
        MOV     DPL, #MOD
        MOV     A, #08H
        MOVX    @DPTR, A        ; clear the reset request bit of the mode register
        RET
        NOP
PROC1:  MOV     DPL, #IR        ; the bus is fine
        MOVX    A, @DPTR        ; read the interrupt bits
        JNB     ACC.3, OTHER
OVER:   MOV     DPL, #CMR       ; data overrun
        MOV     A, #0CH
        MOVX    @DPTR, A        ; clear data overrun, release the receive buffer
        RET
        NOP
OTHER:  JB      ACC.0, RECE
        LJMP    RECOUT          ; nothing in the receive buffer
        NOP
RECE:   MOV     DPL, #FIN       ; a frame is in the receive buffer
        MOVX    A, @DPTR
        JNB     ACC.6, RDATA
        MOV     DPL, #CMR       ; remote frame
        MOV     A, #04H
        MOVX    @DPTR, A
        LJMP    RECOUT
        NOP
RDATA:  MOV     DPL, #FIN       ; start of the received frame
        MOVX    A, @DPTR
        INC     DPL
        MOVX    A, @DPTR
        INC     DPL
        MOVX    A, @DPTR
        INC     DPL
        MOV     R2, #08H
; ----- From here to RECOUT: not in the report (its listing stops above); completed in the
; ----- style of SEND1: copy the 8 data bytes to @R0, then release the receive buffer.
RDATA1: MOVX    A, @DPTR        ; a data byte of the receive buffer
        MOV     @R0, A          ; R0 points at the destination in internal RAM
        INC     R0
        INC     DPL
        DJNZ    R2, RDATA1
        MOV     DPL, #CMR       ; command register: release the receive buffer
        MOV     A, #04H
        MOVX    @DPTR, A
RECOUT: RET

;----- delay subroutine -----
; ----- Not in the report (it calls DELAY but does not show it); written for this file.
; At 12 MHz one machine cycle is 1 us. MOV Rn,#data takes 1 cycle, DJNZ 2, LCALL 2, RET 2
; (Intel MCS-51 User's Manual, instruction set). Inner loop: 248 DJNZ = 496 cycles; each outer
; pass: MOV R6 (1) + 496 + DJNZ R7 (2) = 499 cycles; 200 passes = 99800 cycles. With MOV R7 (1)
; and RET (2): 99803 cycles from DELAY to the return, 99805 with the LCALL: 99.805 ms.
DELAY:  MOV     R7, #200        ; 200 outer passes
DELAY1: MOV     R6, #248        ; 248 inner passes
DELAY2: DJNZ    R6, DELAY2
        DJNZ    R7, DELAY1
        RET
