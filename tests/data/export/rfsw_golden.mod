MODULE rfsw_golden
  ! rfsw-plan program rfsw_golden
  ! rfsw-plan version: 0.1.0
  ! problem: golden
  ! plan id: golden-000000000000
  ! robot: zk500
  ! robot file: zk500.toml
  ! robot file sha256: 0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef
  ! verified tolerated force uncertainty: +-20 %
  ! requested force uncertainty: +-20 %
  ! weld window: -1.250 .. +0.700 mm
  ! points: plan samples every 5 mm of seam
  ! path within 0.01 mm of every verified sample
  ! lengths mm, angles deg, joints = controller axes
  ! Z of every point is its height above the plate surface (the pin tip sits at -depth in the weld)
  ! axial control: position (no force control)
  ! PAYLOAD ASSUMED (robot file: seed 001 §2.1 (electric spindle, 150 kg); centre of mass ASSUMED 250 mm behind the pin tip on the spindle axis): check the spindle's mass and centre of mass before running
  ! PAYLOAD INERTIA UNKNOWN: written as 0; identify it on the controller (load identification)
  ! WARNING: robot zk500 is not a ABB robot (maker not stated): check axis directions, frames and limits on the real controller before running
  ! SPINDLE I/O: NOT in this program: write it in the comments of the spindle start and stop hooks
  ! tFSW and wPlate are this module's own (LOCAL) data
  ! wPlate = the plate: origin on the first weld point, +X along the seam, +Y on the plate. To use a work object taught on the plate, enter its user frame in wPlate and run rfsw-plan check on this file
  LOCAL PERS tooldata tFSW := [TRUE,[[0.0000,0.0000,390.0000],[1.000000000,0.000000000,0.000000000,0.000000000]],[150.000,[0.000,0.000,140.000],[1,0,0,0],0.0000,0.0000,0.0000]];  ! inertia not known: 0, identify it
  LOCAL PERS wobjdata wPlate := [FALSE,TRUE,"",[[-201.1225,-1735.0983,1458.9861],[0.886001721,-0.408478853,0.132177809,0.175142811]],[[0,0,0],[1,0,0,0]]];
  LOCAL CONST zonedata zB1 := [FALSE,0.2,0.2,0.2,0.2,0.2,0.2];  ! mm
  LOCAL CONST zonedata zB2 := [FALSE,0.25,0.25,0.25,0.25,0.25,0.25];  ! mm
  LOCAL CONST zonedata zB3 := [FALSE,0.3,0.3,0.3,0.3,0.3,0.3];  ! mm
  LOCAL CONST zonedata zB4 := [FALSE,0.6,0.6,0.6,0.6,0.6,0.6];  ! mm
  LOCAL CONST zonedata zB5 := [FALSE,1.5,1.5,1.5,1.5,1.5,1.5];  ! mm
  LOCAL CONST jointtarget jStart := [[-96.240000,3.910000,25.450000,-2.100000,57.170000,2.900000],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p2 := [[-9.3811,-15.2507,29.7638],[0.339465494,-0.459962068,0.790241360,0.220718524],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p3 := [[-7.0384,-11.0996,21.9464],[0.342193676,-0.459310879,0.788979607,0.222369476],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p4 := [[-4.6697,-6.9007,14.1626],[0.344917688,-0.458654093,0.787708241,0.224017718],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p5 := [[-2.2750,-2.6542,6.4126],[0.347637497,-0.457991719,0.786427277,0.225663230],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p6 := [[0.1454,1.6398,-1.3032],[0.350353071,-0.457323764,0.785136730,0.227305993],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p7 := [[0.1454,1.6398,-1.3032],[0.350353071,-0.457323764,0.785136730,0.227305993],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p8 := [[0.1454,1.6398,-1.3032],[0.350353071,-0.457323764,0.785136730,0.227305993],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p9 := [[0.1454,1.6398,-1.3032],[0.350353071,-0.457323764,0.785136730,0.227305993],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p10 := [[0.6845,1.3548,-1.3023],[0.350394137,-0.457459385,0.785058245,0.227240866],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p11 := [[1.2356,1.0916,-1.3016],[0.350441974,-0.457593316,0.784976497,0.227179839],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p12 := [[1.7987,0.8503,-1.3009],[0.350496580,-0.457725560,0.784891483,0.227122916],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p13 := [[2.3738,0.6310,-1.3003],[0.350557951,-0.457856117,0.784803204,0.227070099],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p14 := [[2.9608,0.4335,-1.2998],[0.350626086,-0.457984990,0.784711657,0.227021392],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p15 := [[3.5598,0.2579,-1.2994],[0.350700982,-0.458112180,0.784616840,0.226976798],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p16 := [[4.1708,0.1043,-1.2990],[0.350782637,-0.458237687,0.784518751,0.226936321],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p17 := [[4.7936,-0.0274,-1.2988],[0.350871047,-0.458361512,0.784417388,0.226899964],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p18 := [[5.4284,-0.1372,-1.2986],[0.350966210,-0.458483658,0.784312749,0.226867729],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p19 := [[6.0750,-0.2250,-1.2985],[0.351068123,-0.458604124,0.784204831,0.226839620],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p20 := [[6.7336,-0.2909,-1.2984],[0.351176783,-0.458722911,0.784093632,0.226815639],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p21 := [[7.4040,-0.3348,-1.2983],[0.351292188,-0.458840019,0.783979148,0.226795790],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p22 := [[8.0863,-0.3567,-1.2983],[0.351414333,-0.458955451,0.783861377,0.226780076],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p23 := [[8.7804,-0.3566,-1.2982],[0.351543216,-0.459069204,0.783740315,0.226768499],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p24 := [[9.4863,-0.3346,-1.2982],[0.351678833,-0.459181281,0.783615958,0.226761062],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p25 := [[10.2040,-0.2906,-1.2981],[0.351821182,-0.459291681,0.783488304,0.226757768],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p26 := [[10.9335,-0.2246,-1.2979],[0.351970258,-0.459400405,0.783357347,0.226758619],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p27 := [[11.6748,-0.1365,-1.2976],[0.352126059,-0.459507451,0.783223086,0.226763619],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p28 := [[12.4279,-0.0265,-1.2973],[0.352288580,-0.459612821,0.783085514,0.226772769],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p29 := [[13.1927,0.1056,-1.2968],[0.352457818,-0.459716514,0.782944628,0.226786072],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p30 := [[13.9693,0.2597,-1.2962],[0.352633769,-0.459818529,0.782800424,0.226803531],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p31 := [[14.7576,0.4358,-1.2954],[0.352816429,-0.459918867,0.782652896,0.226825148],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p32 := [[15.5575,0.6340,-1.2944],[0.353005794,-0.460017526,0.782502040,0.226850926],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p33 := [[16.3692,0.8543,-1.2931],[0.353201861,-0.460114506,0.782347851,0.226880866],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p34 := [[17.1926,1.0966,-1.2916],[0.353404625,-0.460209806,0.782190323,0.226914971],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p35 := [[18.0276,1.3610,-1.2898],[0.353614081,-0.460303426,0.782029452,0.226953243],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p36 := [[17.5166,0.4649,0.3025],[0.353051019,-0.460442783,0.782301534,0.226609206],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p37 := [[16.4978,-1.3211,3.4917],[0.351924334,-0.460720765,0.782844457,0.225920773],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL CONST robtarget p38 := [[14.9779,-3.9847,8.2867],[0.350232912,-0.461135912,0.783655736,0.224887228],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

  PROC rfsw_golden_run()
    ConfJ\On;
    ConfL\Off;
    ! hook home_start
    ! HOME: move to the cell's home position first (not known to rfsw-plan),
    ! e.g. MoveAbsJ jHome,v100,fine,tFSW;
    ! ---- phase: approach
    MoveAbsJ jStart,v100,fine,tFSW\WObj:=wPlate;
    MoveL p2,v100\V:=91.5588,fine,tFSW\WObj:=wPlate;
    MoveL p3,v100\V:=91.5588,fine,tFSW\WObj:=wPlate;
    MoveL p4,v100\V:=91.5588,fine,tFSW\WObj:=wPlate;
    MoveL p5,v100\V:=91.5588,fine,tFSW\WObj:=wPlate;
    MoveL p6,v100\V:=91.5588,fine,tFSW\WObj:=wPlate;
    ! hook spindle_start
    ! SPINDLE START: spindle on and wait at speed, e.g. SetDO doSpindle, 1;
    ! WaitDI diSpindleAtSpeed, 1;
    ! ---- phase: plunge
    WaitTime\InPos,0.100;
    WaitTime\InPos,0.500;
    ! ---- phase: dwell
    WaitTime\InPos,0.600;
    ! ---- phase: accelerate
    MoveL p10,v100\V:=6.0981,zB1,tFSW\WObj:=wPlate;
    MoveL p11,v100\V:=6.1071,zB1,tFSW\WObj:=wPlate;
    MoveL p12,v100\V:=6.1261,zB1,tFSW\WObj:=wPlate;
    ! ---- phase: weld
    MoveL p13,v100\V:=6.1550,zB1,tFSW\WObj:=wPlate;
    MoveL p14,v100\V:=6.1937,zB1,tFSW\WObj:=wPlate;
    MoveL p15,v100\V:=6.2419,zB1,tFSW\WObj:=wPlate;
    MoveL p16,v100\V:=6.2996,zB2,tFSW\WObj:=wPlate;
    MoveL p17,v100\V:=6.3663,zB2,tFSW\WObj:=wPlate;
    MoveL p18,v100\V:=6.4419,zB2,tFSW\WObj:=wPlate;
    MoveL p19,v100\V:=6.5260,zB2,tFSW\WObj:=wPlate;
    MoveL p20,v100\V:=6.6183,zB2,tFSW\WObj:=wPlate;
    MoveL p21,v100\V:=6.7185,zB2,tFSW\WObj:=wPlate;
    MoveL p22,v100\V:=6.8261,zB2,tFSW\WObj:=wPlate;
    MoveL p23,v100\V:=6.9410,zB2,tFSW\WObj:=wPlate;
    MoveL p24,v100\V:=7.0627,zB2,tFSW\WObj:=wPlate;
    MoveL p25,v100\V:=7.1908,zB2,tFSW\WObj:=wPlate;
    MoveL p26,v100\V:=7.3251,zB2,tFSW\WObj:=wPlate;
    MoveL p27,v100\V:=7.4651,zB2,tFSW\WObj:=wPlate;
    MoveL p28,v100\V:=7.6107,zB3,tFSW\WObj:=wPlate;
    MoveL p29,v100\V:=7.7614,zB3,tFSW\WObj:=wPlate;
    MoveL p30,v100\V:=7.9170,zB3,tFSW\WObj:=wPlate;
    MoveL p31,v100\V:=8.0772,zB3,tFSW\WObj:=wPlate;
    MoveL p32,v100\V:=8.2417,zB3,tFSW\WObj:=wPlate;
    ! ---- phase: decelerate
    MoveL p33,v100\V:=8.4103,zB3,tFSW\WObj:=wPlate;
    MoveL p34,v100\V:=8.5827,zB3,tFSW\WObj:=wPlate;
    MoveL p35,v100\V:=8.7587,fine,tFSW\WObj:=wPlate;
    ! hook force_off
    ! FORCE CONTROL: none (position control)
    ! ---- phase: retract
    MoveL p36,v100\V:=18.9728,zB4,tFSW\WObj:=wPlate;
    ! hook spindle_stop
    ! SPINDLE STOP: the pin has left the material, e.g. SetDO doSpindle, 0;
    MoveL p37,v100\V:=18.9728,zB5,tFSW\WObj:=wPlate;
    MoveL p38,v100\V:=18.9728,fine,tFSW\WObj:=wPlate;
    ! hook home_end
    ! HOME: back to the cell's home position here,
    ! e.g. MoveAbsJ jHome,v100,fine,tFSW;
  ENDPROC
ENDMODULE
