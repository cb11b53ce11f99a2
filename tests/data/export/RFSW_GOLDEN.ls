/PROG  RFSW_GOLDEN
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "golden-000000000";
PROG_SIZE	= 0;
CREATE		= DATE 26-01-01  TIME 00:00:00;
MODIFIED	= DATE 26-01-01  TIME 00:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 63;
MEMORY_SIZE	= 0;
PROTECT		= READ_WRITE;
TCD:  STACK_SIZE	= 0,
      TASK_PRIORITY	= 50,
      TIME_SLICE	= 0,
      BUSY_LAMP_OFF	= 0,
      ABORT_REQUEST	= 0,
      PAUSE_REQUEST	= 0;
DEFAULT_GROUP	= 1,*,*,*,*;
CONTROL_CODE	= 00000000 00000000;
/MN
   1:  ! rfsw-plan program rfsw_golden ;
   2:  ! rfsw-plan version: 0.1.0 ;
   3:  ! problem: golden ;
   4:  ! plan id: golden-000000000000 ;
   5:  ! robot: zk500 ;
   6:  ! robot file: zk500.toml ;
   7:  ! robot file sha256: 0123456789abcdef0123456789abcdef012345678 ;
   8:  !   9abcdef0123456789abcdef ;
   9:  ! verified tolerated force uncertainty: +-20 % ;
  10:  ! requested force uncertainty: +-20 % ;
  11:  ! weld window: -1.250 .. +0.700 mm ;
  12:  ! points: plan samples every 5 mm of seam ;
  13:  ! path within 0.01 mm of every verified sample ;
  14:  ! lengths mm, angles deg, joints = controller axes ;
  15:  ! UFRAME 1 = seam work object in world: ;
  16:  !  X=-201.189 Y=-1735.143 Z=1456.988 W=-0.823 P=2.156 R=12.974 ;
  17:  ! UTOOL 1 = TCP in faceplate: ;
  18:  !  X=0.000 Y=0.000 Z=390.000 W=0.000 P=0.000 R=0.000 ;
  19:  UFRAME_NUM=1 ;
  20:  UTOOL_NUM=1 ;
  21:  ! ---- phase: approach ;
  22:J P[1] 10% FINE ;
  23:L P[2] 0.10sec FINE ;
  24:L P[3] 0.10sec FINE ;
  25:L P[4] 0.10sec FINE ;
  26:L P[5] 0.10sec FINE ;
  27:L P[6] 0.10sec FINE ;
  28:  ! ---- phase: plunge ;
  29:  ! SPINDLE START placeholder: ;
  30:  !  e.g. DO[1]=ON and WAIT DI[1]=ON ;
  31:  WAIT 0.60(sec) ;
  32:  ! ---- phase: dwell ;
  33:  WAIT 0.60(sec) ;
  34:  ! ---- phase: accelerate ;
  35:L P[9] 0.10sec FINE ;
  36:L P[10] 0.10sec CNT100 ;
  37:L P[11] 0.10sec CNT100 ;
  38:  ! ---- phase: weld ;
  39:L P[12] 0.10sec CNT100 ;
  40:L P[13] 0.10sec CNT100 ;
  41:L P[14] 0.10sec CNT100 ;
  42:L P[15] 0.10sec CNT100 ;
  43:L P[16] 0.10sec CNT100 ;
  44:L P[17] 0.10sec CNT100 ;
  45:L P[18] 0.10sec CNT100 ;
  46:L P[19] 0.10sec CNT100 ;
  47:L P[20] 0.10sec CNT100 ;
  48:L P[21] 0.10sec CNT100 ;
  49:L P[22] 0.10sec CNT100 ;
  50:L P[23] 0.10sec CNT100 ;
  51:L P[24] 0.10sec CNT100 ;
  52:L P[25] 0.10sec CNT100 ;
  53:L P[26] 0.10sec CNT100 ;
  54:L P[27] 0.20sec CNT100 ;
  55:L P[28] 8mm/sec CNT100 ;
  56:L P[29] 0.10sec CNT100 ;
  57:  ! ---- phase: decelerate ;
  58:L P[30] 0.20sec CNT100 ;
  59:L P[31] 0.10sec FINE ;
  60:  ! ---- phase: retract ;
  61:  ! SPINDLE STOP placeholder: ;
  62:  !  e.g. DO[1]=OFF ;
  63:  WAIT 0.60(sec) ;
/POS
P[1]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     2.7166  mm,	Y =    13.7020  mm,	Z =    43.6065  mm,
	W = -179.93746 deg,	P =   -1.99807 deg,	R = -111.07631 deg
};
P[2]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     2.0166  mm,	Y =    10.8866  mm,	Z =    34.9224  mm,
	W = -179.95015 deg,	P =   -1.59846 deg,	R = -111.06360 deg
};
P[3]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     1.3372  mm,	Y =     8.1282  mm,	Z =    26.2184  mm,
	W = -179.96275 deg,	P =   -1.19885 deg,	R = -111.05097 deg
};
P[4]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     0.6785  mm,	Y =     5.4272  mm,	Z =    17.4948  mm,
	W = -179.97525 deg,	P =   -0.79924 deg,	R = -111.03844 deg
};
P[5]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     0.0404  mm,	Y =     2.7835  mm,	Z =     8.7522  mm,
	W = -179.98767 deg,	P =   -0.39962 deg,	R = -111.02599 deg
};
P[6]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    -0.5769  mm,	Y =     0.1974  mm,	Z =    -0.0092  mm,
	W = -180.00000 deg,	P =    0.00000 deg,	R = -111.01363 deg
};
P[7]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    -0.5769  mm,	Y =     0.1974  mm,	Z =    -0.0092  mm,
	W = -180.00000 deg,	P =    0.00000 deg,	R = -111.01363 deg
};
P[8]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    -0.5769  mm,	Y =     0.1974  mm,	Z =    -0.0092  mm,
	W = -180.00000 deg,	P =    0.00000 deg,	R = -111.01363 deg
};
P[9]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     0.0000  mm,	Y =     0.0000  mm,	Z =     0.0000  mm,
	W = -179.99948 deg,	P =   -0.00010 deg,	R = -110.99363 deg
};
P[10]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     0.5828  mm,	Y =    -0.1823  mm,	Z =    -0.0098  mm,
	W = -179.99899 deg,	P =    0.00080 deg,	R = -110.97360 deg
};
P[11]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     1.1714  mm,	Y =    -0.3495  mm,	Z =    -0.0387  mm,
	W = -179.99853 deg,	P =    0.00270 deg,	R = -110.95354 deg
};
P[12]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     1.7659  mm,	Y =    -0.5016  mm,	Z =    -0.0865  mm,
	W = -179.99810 deg,	P =    0.00559 deg,	R = -110.93345 deg
};
P[13]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     2.3662  mm,	Y =    -0.6385  mm,	Z =    -0.1533  mm,
	W = -179.99770 deg,	P =    0.00949 deg,	R = -110.91333 deg
};
P[14]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     2.9724  mm,	Y =    -0.7604  mm,	Z =    -0.2392  mm,
	W = -179.99733 deg,	P =    0.01438 deg,	R = -110.89317 deg
};
P[15]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     3.5843  mm,	Y =    -0.8672  mm,	Z =    -0.3440  mm,
	W = -179.99699 deg,	P =    0.02028 deg,	R = -110.87299 deg
};
P[16]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     4.2020  mm,	Y =    -0.9588  mm,	Z =    -0.4678  mm,
	W = -179.99669 deg,	P =    0.02717 deg,	R = -110.85277 deg
};
P[17]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     4.8255  mm,	Y =    -1.0352  mm,	Z =    -0.6105  mm,
	W = -179.99641 deg,	P =    0.03506 deg,	R = -110.83253 deg
};
P[18]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     5.4548  mm,	Y =    -1.0965  mm,	Z =    -0.7723  mm,
	W = -179.99617 deg,	P =    0.04395 deg,	R = -110.81225 deg
};
P[19]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     6.0898  mm,	Y =    -1.1426  mm,	Z =    -0.9530  mm,
	W = -179.99595 deg,	P =    0.05384 deg,	R = -110.79194 deg
};
P[20]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     6.7306  mm,	Y =    -1.1735  mm,	Z =    -1.1527  mm,
	W = -179.99577 deg,	P =    0.06473 deg,	R = -110.77160 deg
};
P[21]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     7.3770  mm,	Y =    -1.1892  mm,	Z =    -1.3713  mm,
	W = -179.99562 deg,	P =    0.07661 deg,	R = -110.75123 deg
};
P[22]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     8.0292  mm,	Y =    -1.1897  mm,	Z =    -1.6088  mm,
	W = -179.99550 deg,	P =    0.08950 deg,	R = -110.73083 deg
};
P[23]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     8.6871  mm,	Y =    -1.1749  mm,	Z =    -1.8653  mm,
	W = -179.99541 deg,	P =    0.10338 deg,	R = -110.71040 deg
};
P[24]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =     9.3507  mm,	Y =    -1.1448  mm,	Z =    -2.1407  mm,
	W = -179.99535 deg,	P =    0.11826 deg,	R = -110.68994 deg
};
P[25]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    10.0199  mm,	Y =    -1.0995  mm,	Z =    -2.4350  mm,
	W = -179.99532 deg,	P =    0.13415 deg,	R = -110.66944 deg
};
P[26]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    10.6949  mm,	Y =    -1.0389  mm,	Z =    -2.7481  mm,
	W = -179.99532 deg,	P =    0.15103 deg,	R = -110.64892 deg
};
P[27]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    12.0617  mm,	Y =    -0.8716  mm,	Z =    -3.4311  mm,
	W = -179.99542 deg,	P =    0.18779 deg,	R = -110.60777 deg
};
P[28]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    13.4510  mm,	Y =    -0.6428  mm,	Z =    -4.1894  mm,
	W = -179.99564 deg,	P =    0.22854 deg,	R = -110.56650 deg
};
P[29]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    14.1542  mm,	Y =    -0.5053  mm,	Z =    -4.5968  mm,
	W = -179.99579 deg,	P =    0.25041 deg,	R = -110.54582 deg
};
P[30]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    15.5772  mm,	Y =    -0.1839  mm,	Z =    -5.4680  mm,
	W = -179.99619 deg,	P =    0.29716 deg,	R = -110.50437 deg
};
P[31]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    16.2972  mm,	Y =     0.0000  mm,	Z =    -5.9317  mm,
	W = -179.99644 deg,	P =    0.32203 deg,	R = -110.48360 deg
};
P[32]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    16.2972  mm,	Y =     0.0000  mm,	Z =    -5.9317  mm,
	W = -179.99644 deg,	P =    0.32203 deg,	R = -110.48360 deg
};
/END
