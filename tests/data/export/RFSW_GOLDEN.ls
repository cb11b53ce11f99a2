/PROG  RFSW_GOLDEN
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "golden-000000000";
PROG_SIZE	= 0;
CREATE		= DATE 00-01-01  TIME 00:00:00;
MODIFIED	= DATE 00-01-01  TIME 00:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 187;
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
   7:  ! robot file sha256: ;
   8:  ! 0123456789abcdef0123456789abcdef ;
   9:  ! 0123456789abcdef0123456789abcdef ;
  10:  ! verified tolerated force ;
  11:  ! uncertainty: +-20 % ;
  12:  ! requested force uncertainty: ;
  13:  ! +-20 % ;
  14:  ! weld window: -1.250 .. +0.700 mm ;
  15:  ! points: plan samples every 5 mm ;
  16:  ! of seam ;
  17:  ! path within 0.01 mm of every ;
  18:  ! verified sample ;
  19:  ! lengths mm, angles deg, joints = ;
  20:  ! controller axes ;
  21:  ! Z of every point is its height ;
  22:  ! above the plate surface (the pin ;
  23:  ! tip sits at -depth in the weld) ;
  24:  ! axial control: position (no ;
  25:  ! force control) ;
  26:  ! PAYLOAD ASSUMED (robot file: ;
  27:  ! seed 001 sec. 2.1 (electric ;
  28:  ! spindle, 150 kg), centre of mass ;
  29:  ! ASSUMED 250 mm behind the pin ;
  30:  ! tip on the spindle axis): check ;
  31:  ! the spindle's mass and centre of ;
  32:  ! mass before running ;
  33:  ! PAYLOAD INERTIA UNKNOWN: written ;
  34:  ! as 0, identify it on the ;
  35:  ! controller (load identification) ;
  36:  ! WARNING: robot zk500 is not a ;
  37:  ! FANUC robot (maker not stated): ;
  38:  ! check axis directions, frames ;
  39:  ! and limits on the real ;
  40:  ! controller before running ;
  41:  ! CELL DATA LEFT ALONE: this ;
  42:  ! program selects UFRAME 1 and ;
  43:  ! UTOOL 1 and writes no frame, ;
  44:  ! register or payload: enter the ;
  45:  ! values of the UFRAME/UTOOL ;
  46:  ! remarks below there and select ;
  47:  ! the payload schedule before ;
  48:  ! running ;
  49:  ! SPINDLE I/O: NOT in this ;
  50:  ! program: write it in the ;
  51:  ! comments of the spindle start ;
  52:  ! and stop hooks ;
  53:  ! SPEED REGISTER R[20]: set before ;
  54:  ! each move whose speed is not a ;
  55:  ! whole mm/sec (export option ;
  56:  ! speed_register) ;
  57:  ! PAYLOAD (payload screen): 150.0 ;
  58:  ! kg ASSUMED, centre X 0.00 Y 0.00 ;
  59:  ! Z 14.00 cm (faceplate), inertia ;
  60:  ! UNKNOWN (0, identify it) ;
  61:  ! UFRAME = the plate: origin on ;
  62:  ! the first weld point, +X along ;
  63:  ! the seam, +Y on the plate. To ;
  64:  ! use a frame taught on the plate ;
  65:  ! (3-point), enter it in the ;
  66:  ! UFRAME remarks and run rfsw-plan ;
  67:  ! check on this file ;
  68:  ! Termination: CR (corner region, ;
  69:  ! mm) at 27 points inside the ;
  70:  ! plunge, dwell, weld and retract, ;
  71:  ! FINE at the phase ends, CRy ;
  72:  ! keeps the corner path within y ;
  73:  ! mm of the point (half the ;
  74:  ! segment at most): it needs the ;
  75:  ! Advanced Constant Path option ;
  76:  ! (without it replace CRn by FINE) ;
  77:  ! UFRAME[1] X -201.1225 ;
  78:  ! UFRAME[1] Y -1735.0983 ;
  79:  ! UFRAME[1] Z 1458.9861 ;
  80:  ! UFRAME[1] W -47.0206 ;
  81:  ! UFRAME[1] P 22.1668 ;
  82:  ! UFRAME[1] R 12.6222 ;
  83:  ! UTOOL[1] X 0.0000 ;
  84:  ! UTOOL[1] Y 0.0000 ;
  85:  ! UTOOL[1] Z 390.0000 ;
  86:  ! UTOOL[1] W 0.0000 ;
  87:  ! UTOOL[1] P 0.0000 ;
  88:  ! UTOOL[1] R 0.0000 ;
  89:  UFRAME_NUM=1 ;
  90:  UTOOL_NUM=1 ;
  91:  ! hook home_start ;
  92:  ! HOME: move to the cell's home ;
  93:  ! first, ;
  94:  ! e.g. J PR[1:HOME] 10% FINE ;
  95:  ! ---- phase: approach ;
  96:J P[1] 10% FINE ;
  97:  R[20]=91.558485 ;
  98:L P[2] R[20]mm/sec FINE ;
  99:  R[20]=91.559608 ;
 100:L P[3] R[20]mm/sec FINE ;
 101:  R[20]=91.558202 ;
 102:L P[4] R[20]mm/sec FINE ;
 103:  R[20]=91.558643 ;
 104:L P[5] R[20]mm/sec FINE ;
 105:  R[20]=91.558911 ;
 106:L P[6] R[20]mm/sec FINE ;
 107:  ! hook spindle_start ;
 108:  ! SPINDLE START: spindle on and ;
 109:  ! wait at speed, ;
 110:  ! e.g. DO[1]=ON and WAIT DI[1]=ON ;
 111:  ! ---- phase: plunge ;
 112:  WAIT 0.10(sec) ;
 113:  WAIT 0.50(sec) ;
 114:  ! ---- phase: dwell ;
 115:  WAIT 0.60(sec) ;
 116:  ! ---- phase: accelerate ;
 117:  R[20]=6.097988 ;
 118:L P[10] R[20]mm/sec CR1 ;
 119:  R[20]=6.107257 ;
 120:L P[11] R[20]mm/sec CR1 ;
 121:  R[20]=6.126237 ;
 122:L P[12] R[20]mm/sec CR1 ;
 123:  ! ---- phase: weld ;
 124:  R[20]=6.154940 ;
 125:L P[13] R[20]mm/sec CR1 ;
 126:  R[20]=6.193347 ;
 127:L P[14] R[20]mm/sec CR1 ;
 128:  R[20]=6.242087 ;
 129:L P[15] R[20]mm/sec CR1 ;
 130:  R[20]=6.300112 ;
 131:L P[16] R[20]mm/sec CR1 ;
 132:  R[20]=6.365727 ;
 133:L P[17] R[20]mm/sec CR1 ;
 134:  R[20]=6.442260 ;
 135:L P[18] R[20]mm/sec CR1 ;
 136:  R[20]=6.525338 ;
 137:L P[19] R[20]mm/sec CR1 ;
 138:  R[20]=6.618888 ;
 139:L P[20] R[20]mm/sec CR1 ;
 140:  R[20]=6.718358 ;
 141:L P[21] R[20]mm/sec CR1 ;
 142:  R[20]=6.826514 ;
 143:L P[22] R[20]mm/sec CR1 ;
 144:  R[20]=6.941000 ;
 145:L P[23] R[20]mm/sec CR1 ;
 146:  R[20]=7.062427 ;
 147:L P[24] R[20]mm/sec CR1 ;
 148:  R[20]=7.190475 ;
 149:L P[25] R[20]mm/sec CR1 ;
 150:  R[20]=7.324795 ;
 151:L P[26] R[20]mm/sec CR1 ;
 152:  R[20]=7.465168 ;
 153:L P[27] R[20]mm/sec CR1 ;
 154:  R[20]=7.610911 ;
 155:L P[28] R[20]mm/sec CR1 ;
 156:  R[20]=7.761248 ;
 157:L P[29] R[20]mm/sec CR1 ;
 158:  R[20]=7.917416 ;
 159:L P[30] R[20]mm/sec CR1 ;
 160:  R[20]=8.077306 ;
 161:L P[31] R[20]mm/sec CR1 ;
 162:  R[20]=8.240900 ;
 163:L P[32] R[20]mm/sec CR1 ;
 164:  ! ---- phase: decelerate ;
 165:  R[20]=8.410652 ;
 166:L P[33] R[20]mm/sec CR1 ;
 167:  R[20]=8.583118 ;
 168:L P[34] R[20]mm/sec CR1 ;
 169:  R[20]=8.758628 ;
 170:L P[35] R[20]mm/sec FINE ;
 171:  ! hook force_off ;
 172:  ! FORCE CONTROL: none (position ;
 173:  ! control) ;
 174:  ! ---- phase: retract ;
 175:  R[20]=18.972442 ;
 176:L P[36] R[20]mm/sec CR7 ;
 177:  ! hook spindle_stop ;
 178:  ! SPINDLE STOP: the pin has left ;
 179:  ! the material, ;
 180:  ! e.g. DO[1]=OFF ;
 181:  R[20]=18.972840 ;
 182:L P[37] R[20]mm/sec CR3 ;
 183:  R[20]=18.972754 ;
 184:L P[38] R[20]mm/sec FINE ;
 185:  ! hook home_end ;
 186:  ! HOME: back to the cell's home, ;
 187:  ! e.g. J PR[1:HOME] 10% FINE ;
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
	X =     0.1454  mm,	Y =     1.6398  mm,	Z =    -1.3032  mm,
	W =  176.79325 deg,	P =   49.29303 deg,	R = -121.03202 deg
};
P[10]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     0.6845  mm,	Y =     1.3548  mm,	Z =    -1.3023  mm,
	W =  176.81699 deg,	P =   49.29404 deg,	R = -121.00140 deg
};
P[11]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     1.2356  mm,	Y =     1.0916  mm,	Z =    -1.3016  mm,
	W =  176.84067 deg,	P =   49.29605 deg,	R = -120.97081 deg
};
P[12]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     1.7987  mm,	Y =     0.8503  mm,	Z =    -1.3009  mm,
	W =  176.86429 deg,	P =   49.29905 deg,	R = -120.94025 deg
};
P[13]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     2.3738  mm,	Y =     0.6310  mm,	Z =    -1.3003  mm,
	W =  176.88786 deg,	P =   49.30303 deg,	R = -120.90973 deg
};
P[14]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     2.9608  mm,	Y =     0.4335  mm,	Z =    -1.2998  mm,
	W =  176.91138 deg,	P =   49.30801 deg,	R = -120.87923 deg
};
P[15]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     3.5598  mm,	Y =     0.2579  mm,	Z =    -1.2994  mm,
	W =  176.93484 deg,	P =   49.31398 deg,	R = -120.84877 deg
};
P[16]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     4.1708  mm,	Y =     0.1043  mm,	Z =    -1.2990  mm,
	W =  176.95825 deg,	P =   49.32094 deg,	R = -120.81833 deg
};
P[17]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     4.7936  mm,	Y =    -0.0274  mm,	Z =    -1.2988  mm,
	W =  176.98162 deg,	P =   49.32890 deg,	R = -120.78792 deg
};
P[18]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     5.4284  mm,	Y =    -0.1372  mm,	Z =    -1.2986  mm,
	W =  177.00493 deg,	P =   49.33784 deg,	R = -120.75753 deg
};
P[19]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     6.0750  mm,	Y =    -0.2250  mm,	Z =    -1.2985  mm,
	W =  177.02820 deg,	P =   49.34777 deg,	R = -120.72716 deg
};
P[20]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     6.7336  mm,	Y =    -0.2909  mm,	Z =    -1.2984  mm,
	W =  177.05143 deg,	P =   49.35870 deg,	R = -120.69681 deg
};
P[21]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     7.4040  mm,	Y =    -0.3348  mm,	Z =    -1.2983  mm,
	W =  177.07461 deg,	P =   49.37062 deg,	R = -120.66648 deg
};
P[22]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     8.0863  mm,	Y =    -0.3567  mm,	Z =    -1.2983  mm,
	W =  177.09774 deg,	P =   49.38352 deg,	R = -120.63616 deg
};
P[23]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     8.7804  mm,	Y =    -0.3566  mm,	Z =    -1.2982  mm,
	W =  177.12084 deg,	P =   49.39742 deg,	R = -120.60586 deg
};
P[24]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =     9.4863  mm,	Y =    -0.3346  mm,	Z =    -1.2982  mm,
	W =  177.14390 deg,	P =   49.41231 deg,	R = -120.57557 deg
};
P[25]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    10.2040  mm,	Y =    -0.2906  mm,	Z =    -1.2981  mm,
	W =  177.16691 deg,	P =   49.42820 deg,	R = -120.54528 deg
};
P[26]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    10.9335  mm,	Y =    -0.2246  mm,	Z =    -1.2979  mm,
	W =  177.18990 deg,	P =   49.44507 deg,	R = -120.51501 deg
};
P[27]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    11.6748  mm,	Y =    -0.1365  mm,	Z =    -1.2976  mm,
	W =  177.21284 deg,	P =   49.46293 deg,	R = -120.48474 deg
};
P[28]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    12.4279  mm,	Y =    -0.0265  mm,	Z =    -1.2973  mm,
	W =  177.23575 deg,	P =   49.48179 deg,	R = -120.45448 deg
};
P[29]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    13.1927  mm,	Y =     0.1056  mm,	Z =    -1.2968  mm,
	W =  177.25863 deg,	P =   49.50164 deg,	R = -120.42422 deg
};
P[30]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    13.9693  mm,	Y =     0.2597  mm,	Z =    -1.2962  mm,
	W =  177.28148 deg,	P =   49.52247 deg,	R = -120.39396 deg
};
P[31]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    14.7576  mm,	Y =     0.4358  mm,	Z =    -1.2954  mm,
	W =  177.30430 deg,	P =   49.54430 deg,	R = -120.36370 deg
};
P[32]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    15.5575  mm,	Y =     0.6340  mm,	Z =    -1.2944  mm,
	W =  177.32709 deg,	P =   49.56713 deg,	R = -120.33344 deg
};
P[33]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    16.3692  mm,	Y =     0.8543  mm,	Z =    -1.2931  mm,
	W =  177.34985 deg,	P =   49.59094 deg,	R = -120.30318 deg
};
P[34]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    17.1926  mm,	Y =     1.0966  mm,	Z =    -1.2916  mm,
	W =  177.37259 deg,	P =   49.61574 deg,	R = -120.27290 deg
};
P[35]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    18.0276  mm,	Y =     1.3610  mm,	Z =    -1.2898  mm,
	W =  177.39530 deg,	P =   49.64154 deg,	R = -120.24262 deg
};
P[36]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    17.5166  mm,	Y =     0.4649  mm,	Z =     0.3025  mm,
	W =  177.39929 deg,	P =   49.55825 deg,	R = -120.24074 deg
};
P[37]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    16.4978  mm,	Y =    -1.3211  mm,	Z =     3.4917  mm,
	W =  177.40724 deg,	P =   49.39168 deg,	R = -120.23702 deg
};
P[38]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    14.9779  mm,	Y =    -3.9847  mm,	Z =     8.2867  mm,
	W =  177.41908 deg,	P =   49.14182 deg,	R = -120.23153 deg
};
/END
