/PROG  RFSW_GOLDEN
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "golden-000000000";
PROG_SIZE	= 0;
CREATE		= DATE 00-01-01  TIME 00:00:00;
MODIFIED	= DATE 00-01-01  TIME 00:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 99;
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
  15:  ! PAYLOAD ASSUMED (robot file: seed 001 §2.1 (electric ;
  16:  !   spindle, 150 kg); centre of mass ASSUMED 250 mm behind ;
  17:  !   the pin tip on the spindle axis): check the spindle's ;
  18:  !   mass and centre of mass before running ;
  19:  ! PAYLOAD INERTIA UNKNOWN: written as 0; identify it on the ;
  20:  !   controller (load identification) ;
  21:  ! WARNING: robot zk500 is not a FANUC robot (maker not ;
  22:  !   stated): check axis directions, frames and limits on the ;
  23:  !   real controller before running ;
  24:  ! CELL DATA LEFT ALONE: this program selects UFRAME 1 and ;
  25:  !   UTOOL 1 and writes no frame, register or payload: enter ;
  26:  !   the values of the UFRAME/UTOOL remarks below there and ;
  27:  !   select the payload schedule before running ;
  28:  ! SET ON THE CONTROLLER: the spindle I/O in the hook remarks ;
  29:  ! PAYLOAD (payload screen): 150.0 kg ASSUMED, centre X 0.00 Y ;
  30:  !   0.00 Z 14.00 cm (faceplate), inertia UNKNOWN (0; identify ;
  31:  !   it) ;
  32:  ! UFRAME = the plate: origin on the first weld point, +X ;
  33:  !   along the seam, +Y on the plate. To use a frame taught on ;
  34:  !   the plate (3-point), enter it in the UFRAME remarks and ;
  35:  !   run rfsw-plan check on this file ;
  36:  ! Termination: CR (corner region, mm) at 24 points inside the ;
  37:  !   plunge, dwell and weld, FINE at the phase ends; CRy keeps ;
  38:  !   the corner path within y mm of the point (half the ;
  39:  !   segment at most): it needs the Advanced Constant Path ;
  40:  !   option (without it replace CRn by FINE) ;
  41:  ! UFRAME[1] X -201.1225 Y -1735.0983 Z 1458.9861 ;
  42:  ! UFRAME[1] W -47.0206 P 22.1668 R 12.6222 ;
  43:  ! UTOOL[1] X 0.0000 Y 0.0000 Z 390.0000 ;
  44:  ! UTOOL[1] W 0.0000 P 0.0000 R 0.0000 ;
  45:  UFRAME_NUM=1 ;
  46:  UTOOL_NUM=1 ;
  47:  ! HOME: move to the cell's home first, ;
  48:  !  e.g. J PR[1:HOME] 10% FINE ;
  49:  ! ---- phase: approach ;
  50:J P[1] 10% FINE ;
  51:L P[2] 100msec FINE ;
  52:L P[3] 100msec FINE ;
  53:L P[4] 100msec FINE ;
  54:L P[5] 100msec FINE ;
  55:L P[6] 100msec FINE ;
  56:  ! SPINDLE START: spindle on and wait at speed, ;
  57:  !  e.g. DO[1]=ON and WAIT DI[1]=ON ;
  58:  ! FORCE CONTROL ON here if used ;
  59:  ! ---- phase: plunge ;
  60:  WAIT 0.60(sec) ;
  61:  ! ---- phase: dwell ;
  62:  WAIT 0.60(sec) ;
  63:  ! ---- phase: accelerate ;
  64:L P[9] 100msec FINE ;
  65:L P[10] 100msec CR1 ;
  66:L P[11] 100msec CR1 ;
  67:  ! ---- phase: weld ;
  68:L P[12] 100msec CR1 ;
  69:L P[13] 100msec CR1 ;
  70:L P[14] 100msec CR1 ;
  71:L P[15] 100msec CR1 ;
  72:L P[16] 100msec CR1 ;
  73:L P[17] 100msec CR1 ;
  74:L P[18] 100msec CR1 ;
  75:L P[19] 100msec CR1 ;
  76:L P[20] 100msec CR1 ;
  77:L P[21] 100msec CR1 ;
  78:L P[22] 100msec CR1 ;
  79:L P[23] 100msec CR1 ;
  80:L P[24] 100msec CR1 ;
  81:L P[25] 100msec CR1 ;
  82:L P[26] 100msec CR1 ;
  83:L P[27] 100msec CR1 ;
  84:L P[28] 100msec CR1 ;
  85:L P[29] 100msec CR1 ;
  86:L P[30] 100msec CR1 ;
  87:L P[31] 100msec CR1 ;
  88:  ! ---- phase: decelerate ;
  89:L P[32] 100msec CR1 ;
  90:L P[33] 100msec CR1 ;
  91:L P[34] 100msec FINE ;
  92:  ! FORCE CONTROL OFF here if used ;
  93:  ! ---- phase: retract ;
  94:L P[35] 300msec FINE ;
  95:  ! SPINDLE STOP: the pin has left the material, ;
  96:  !  e.g. DO[1]=OFF ;
  97:L P[36] 300msec FINE ;
  98:  ! HOME: back to the cell's home, ;
  99:  !  e.g. J PR[1:HOME] 10% FINE ;
/POS
P[1]{
   GP1:
	UF : 1, UT : 1,
	J1=   -96.240000 deg,	J2=     3.910000 deg,	J3=    25.450000 deg,
	J4=    -2.100000 deg,	J5=    57.170000 deg,	J6=     2.900000 deg
};
P[2]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    -9.3811  mm,	Y =   -15.2507  mm,	Z =    29.7638  mm,
	W =  176.88640 deg,	P =   47.69426 deg,	R = -120.97328 deg
};
P[3]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    -7.0384  mm,	Y =   -11.0996  mm,	Z =    21.9464  mm,
	W =  176.86361 deg,	P =   48.09396 deg,	R = -120.98743 deg
};
P[4]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    -4.6697  mm,	Y =    -6.9007  mm,	Z =    14.1626  mm,
	W =  176.84050 deg,	P =   48.49365 deg,	R = -121.00193 deg
};
P[5]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    -2.2750  mm,	Y =    -2.6542  mm,	Z =     6.4126  mm,
	W =  176.81705 deg,	P =   48.89334 deg,	R = -121.01679 deg
};
P[6]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     0.1454  mm,	Y =     1.6398  mm,	Z =    -1.3032  mm,
	W =  176.79325 deg,	P =   49.29303 deg,	R = -121.03202 deg
};
P[7]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     0.1454  mm,	Y =     1.6398  mm,	Z =    -1.3032  mm,
	W =  176.79325 deg,	P =   49.29303 deg,	R = -121.03202 deg
};
P[8]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     0.1454  mm,	Y =     1.6398  mm,	Z =    -1.3032  mm,
	W =  176.79325 deg,	P =   49.29303 deg,	R = -121.03202 deg
};
P[9]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     0.6845  mm,	Y =     1.3548  mm,	Z =    -1.3023  mm,
	W =  176.81699 deg,	P =   49.29404 deg,	R = -121.00140 deg
};
P[10]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     1.2356  mm,	Y =     1.0916  mm,	Z =    -1.3016  mm,
	W =  176.84067 deg,	P =   49.29605 deg,	R = -120.97081 deg
};
P[11]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     1.7987  mm,	Y =     0.8503  mm,	Z =    -1.3009  mm,
	W =  176.86429 deg,	P =   49.29905 deg,	R = -120.94025 deg
};
P[12]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     2.3738  mm,	Y =     0.6310  mm,	Z =    -1.3003  mm,
	W =  176.88786 deg,	P =   49.30303 deg,	R = -120.90973 deg
};
P[13]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     2.9608  mm,	Y =     0.4335  mm,	Z =    -1.2998  mm,
	W =  176.91138 deg,	P =   49.30801 deg,	R = -120.87923 deg
};
P[14]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     3.5598  mm,	Y =     0.2579  mm,	Z =    -1.2994  mm,
	W =  176.93484 deg,	P =   49.31398 deg,	R = -120.84877 deg
};
P[15]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     4.1708  mm,	Y =     0.1043  mm,	Z =    -1.2990  mm,
	W =  176.95825 deg,	P =   49.32094 deg,	R = -120.81833 deg
};
P[16]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     4.7936  mm,	Y =    -0.0274  mm,	Z =    -1.2988  mm,
	W =  176.98162 deg,	P =   49.32890 deg,	R = -120.78792 deg
};
P[17]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     5.4284  mm,	Y =    -0.1372  mm,	Z =    -1.2986  mm,
	W =  177.00493 deg,	P =   49.33784 deg,	R = -120.75753 deg
};
P[18]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     6.0750  mm,	Y =    -0.2250  mm,	Z =    -1.2985  mm,
	W =  177.02820 deg,	P =   49.34777 deg,	R = -120.72716 deg
};
P[19]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     6.7336  mm,	Y =    -0.2909  mm,	Z =    -1.2984  mm,
	W =  177.05143 deg,	P =   49.35870 deg,	R = -120.69681 deg
};
P[20]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     7.4040  mm,	Y =    -0.3348  mm,	Z =    -1.2983  mm,
	W =  177.07461 deg,	P =   49.37062 deg,	R = -120.66648 deg
};
P[21]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     8.0863  mm,	Y =    -0.3567  mm,	Z =    -1.2983  mm,
	W =  177.09774 deg,	P =   49.38352 deg,	R = -120.63616 deg
};
P[22]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     8.7804  mm,	Y =    -0.3566  mm,	Z =    -1.2982  mm,
	W =  177.12084 deg,	P =   49.39742 deg,	R = -120.60586 deg
};
P[23]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     9.4863  mm,	Y =    -0.3346  mm,	Z =    -1.2982  mm,
	W =  177.14390 deg,	P =   49.41231 deg,	R = -120.57557 deg
};
P[24]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    10.2040  mm,	Y =    -0.2906  mm,	Z =    -1.2981  mm,
	W =  177.16691 deg,	P =   49.42820 deg,	R = -120.54528 deg
};
P[25]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    10.9335  mm,	Y =    -0.2246  mm,	Z =    -1.2979  mm,
	W =  177.18990 deg,	P =   49.44507 deg,	R = -120.51501 deg
};
P[26]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    11.6748  mm,	Y =    -0.1365  mm,	Z =    -1.2976  mm,
	W =  177.21284 deg,	P =   49.46293 deg,	R = -120.48474 deg
};
P[27]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    12.4279  mm,	Y =    -0.0265  mm,	Z =    -1.2973  mm,
	W =  177.23575 deg,	P =   49.48179 deg,	R = -120.45448 deg
};
P[28]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    13.1927  mm,	Y =     0.1056  mm,	Z =    -1.2968  mm,
	W =  177.25863 deg,	P =   49.50164 deg,	R = -120.42422 deg
};
P[29]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    13.9693  mm,	Y =     0.2597  mm,	Z =    -1.2962  mm,
	W =  177.28148 deg,	P =   49.52247 deg,	R = -120.39396 deg
};
P[30]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    14.7576  mm,	Y =     0.4358  mm,	Z =    -1.2954  mm,
	W =  177.30430 deg,	P =   49.54430 deg,	R = -120.36370 deg
};
P[31]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    15.5575  mm,	Y =     0.6340  mm,	Z =    -1.2944  mm,
	W =  177.32709 deg,	P =   49.56713 deg,	R = -120.33344 deg
};
P[32]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    16.3692  mm,	Y =     0.8543  mm,	Z =    -1.2931  mm,
	W =  177.34985 deg,	P =   49.59094 deg,	R = -120.30318 deg
};
P[33]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    17.1926  mm,	Y =     1.0966  mm,	Z =    -1.2916  mm,
	W =  177.37259 deg,	P =   49.61574 deg,	R = -120.27290 deg
};
P[34]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    18.0276  mm,	Y =     1.3610  mm,	Z =    -1.2898  mm,
	W =  177.39530 deg,	P =   49.64154 deg,	R = -120.24262 deg
};
P[35]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    16.4978  mm,	Y =    -1.3211  mm,	Z =     3.4917  mm,
	W =  177.40724 deg,	P =   49.39168 deg,	R = -120.23702 deg
};
P[36]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    14.9779  mm,	Y =    -3.9847  mm,	Z =     8.2867  mm,
	W =  177.41908 deg,	P =   49.14182 deg,	R = -120.23153 deg
};
/END
