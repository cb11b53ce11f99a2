%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

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
  PERS tooldata tFSW := [TRUE,[[0.0000,0.0000,390.0000],[1.000000000,0.000000000,0.000000000,0.000000000]],[1,[0,0,1],[1,0,0,0],0,0,0]];  ! load data: placeholder, enter the spindle's
  PERS wobjdata wSeam := [FALSE,TRUE,"",[[-201.1894,-1735.1432,1456.9877],[0.993380660,-0.009262574,0.017880333,0.113090064]],[[0,0,0],[1,0,0,0]]];
  CONST speeddata vS1 := [91.5588,30,5000,1000];  ! mm/s
  CONST speeddata vS2 := [6.0981,30,5000,1000];  ! mm/s
  CONST speeddata vS3 := [6.1071,30,5000,1000];  ! mm/s
  CONST speeddata vS4 := [6.1261,30,5000,1000];  ! mm/s
  CONST speeddata vS5 := [6.1550,30,5000,1000];  ! mm/s
  CONST speeddata vS6 := [6.1937,30,5000,1000];  ! mm/s
  CONST speeddata vS7 := [6.2419,30,5000,1000];  ! mm/s
  CONST speeddata vS8 := [6.2996,30,5000,1000];  ! mm/s
  CONST speeddata vS9 := [6.3663,30,5000,1000];  ! mm/s
  CONST speeddata vS10 := [6.4419,30,5000,1000];  ! mm/s
  CONST speeddata vS11 := [6.5260,30,5000,1000];  ! mm/s
  CONST speeddata vS12 := [6.6183,30,5000,1000];  ! mm/s
  CONST speeddata vS13 := [6.7185,30,5000,1000];  ! mm/s
  CONST speeddata vS14 := [6.8261,30,5000,1000];  ! mm/s
  CONST speeddata vS15 := [6.9410,30,5000,1000];  ! mm/s
  CONST speeddata vS16 := [7.0627,30,5000,1000];  ! mm/s
  CONST speeddata vS17 := [7.1908,30,5000,1000];  ! mm/s
  CONST speeddata vS18 := [7.3251,30,5000,1000];  ! mm/s
  CONST speeddata vS19 := [7.4651,30,5000,1000];  ! mm/s
  CONST speeddata vS20 := [7.6854,30,5000,1000];  ! mm/s
  CONST speeddata vS21 := [7.9965,30,5000,1000];  ! mm/s
  CONST speeddata vS22 := [8.2417,30,5000,1000];  ! mm/s
  CONST speeddata vS23 := [8.4960,30,5000,1000];  ! mm/s
  CONST speeddata vS24 := [8.7587,30,5000,1000];  ! mm/s
  CONST zonedata zB1 := [FALSE,0.2443,0.3664,0.3664,0.0366,0.3664,0.0366];  ! mm
  CONST zonedata zB2 := [FALSE,0.2450,0.3675,0.3675,0.0367,0.3675,0.0367];  ! mm
  CONST zonedata zB3 := [FALSE,0.2462,0.3693,0.3693,0.0369,0.3693,0.0369];  ! mm
  CONST zonedata zB4 := [FALSE,0.2477,0.3715,0.3715,0.0372,0.3715,0.0372];  ! mm
  CONST zonedata zB5 := [FALSE,0.2497,0.3745,0.3745,0.0375,0.3745,0.0375];  ! mm
  CONST zonedata zB6 := [FALSE,0.2520,0.3780,0.3780,0.0378,0.3780,0.0378];  ! mm
  CONST zonedata zB7 := [FALSE,0.2547,0.3821,0.3821,0.0382,0.3821,0.0382];  ! mm
  CONST zonedata zB8 := [FALSE,0.2577,0.3865,0.3865,0.0387,0.3865,0.0387];  ! mm
  CONST zonedata zB9 := [FALSE,0.2610,0.3915,0.3915,0.0391,0.3915,0.0391];  ! mm
  CONST zonedata zB10 := [FALSE,0.2647,0.3971,0.3971,0.0397,0.3971,0.0397];  ! mm
  CONST zonedata zB11 := [FALSE,0.2687,0.4031,0.4031,0.0403,0.4031,0.0403];  ! mm
  CONST zonedata zB12 := [FALSE,0.2730,0.4095,0.4095,0.0410,0.4095,0.0410];  ! mm
  CONST zonedata zB13 := [FALSE,0.2776,0.4164,0.4164,0.0416,0.4164,0.0416];  ! mm
  CONST zonedata zB14 := [FALSE,0.2825,0.4237,0.4237,0.0424,0.4237,0.0424];  ! mm
  CONST zonedata zB15 := [FALSE,0.2876,0.4314,0.4314,0.0431,0.4314,0.0431];  ! mm
  CONST zonedata zB16 := [FALSE,0.2930,0.4395,0.4395,0.0439,0.4395,0.0439];  ! mm
  CONST zonedata zB17 := [FALSE,0.2986,0.4479,0.4479,0.0448,0.4479,0.0448];  ! mm
  CONST zonedata zB18 := [FALSE,0.6148,0.9222,0.9222,0.0922,0.9222,0.0922];  ! mm
  CONST zonedata zB19 := [FALSE,0.3297,0.4945,0.4945,0.0495,0.4945,0.0495];  ! mm
  CONST zonedata zB20 := [FALSE,0.3503,0.5254,0.5254,0.0525,0.5254,0.0525];  ! mm
  CONST robtarget p1 := [[2.7166,13.7020,43.6065],[0.014066949,0.565779037,-0.824372358,0.010315942],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p2 := [[2.0166,10.8866,34.9224],[0.011253765,0.565898661,-0.824356687,0.008252904],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p3 := [[1.3372,8.1282,26.2184],[0.008440444,0.566011390,-0.824330972,0.006189766],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p4 := [[0.6785,5.4272,17.4948],[0.005627020,0.566117222,-0.824295213,0.004126553],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p5 := [[0.0404,2.7835,8.7522],[0.002813527,0.566216157,-0.824249411,0.002063289],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p6 := [[-0.5769,0.1974,-0.0092],[0.000000000,0.566308192,-0.824193564,0.000000000],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p7 := [[-0.5769,0.1974,-0.0092],[0.000000000,0.566308192,-0.824193564,0.000000000],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p8 := [[-0.5769,0.1974,-0.0092],[0.000000000,0.566308192,-0.824193564,0.000000000],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p9 := [[0.0000,0.0000,0.0000],[0.000001864,-0.566452026,0.824094717,-0.000004251],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p10 := [[0.5828,-0.1823,-0.0098],[0.000010758,-0.566596065,0.823995691,-0.000003340],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p11 := [[1.1714,-0.3495,-0.0387],[0.000026682,-0.566740308,0.823896488,0.000002737],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p12 := [[1.7659,-0.5016,-0.0865],[0.000049631,-0.566884754,0.823797107,0.000013983],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p13 := [[2.3662,-0.6385,-0.1533],[0.000079603,-0.567029404,0.823697546,0.000030401],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p14 := [[2.9724,-0.7604,-0.2392],[0.000116595,-0.567174258,0.823597805,0.000051997],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p15 := [[3.5843,-0.8672,-0.3440],[0.000160605,-0.567319313,0.823497884,0.000078773],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p16 := [[4.2020,-0.9588,-0.4678],[0.000211629,-0.567464571,0.823397780,0.000110732],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p17 := [[4.8255,-1.0352,-0.6105],[0.000269666,-0.567610029,0.823297492,0.000147880],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p18 := [[5.4548,-1.0965,-0.7723],[0.000334712,-0.567755687,0.823197019,0.000190219],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p19 := [[6.0898,-1.1426,-0.9530],[0.000406765,-0.567901543,0.823096358,0.000237752],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p20 := [[6.7306,-1.1735,-1.1527],[0.000485822,-0.568047597,0.822995509,0.000290485],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p21 := [[7.3770,-1.1892,-1.3713],[0.000571881,-0.568193847,0.822894467,0.000348420],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p22 := [[8.0292,-1.1897,-1.6088],[0.000664937,-0.568340291,0.822793232,0.000411560],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p23 := [[8.6871,-1.1749,-1.8653],[0.000764990,-0.568486928,0.822691800,0.000479911],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p24 := [[9.3507,-1.1448,-2.1407],[0.000872036,-0.568633756,0.822590168,0.000553474],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p25 := [[10.0199,-1.0995,-2.4350],[0.000986072,-0.568780773,0.822488334,0.000632255],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p26 := [[10.6949,-1.0389,-2.7481],[0.001107096,-0.568927977,0.822386295,0.000716257],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p27 := [[12.0617,-0.8716,-3.4311],[0.001370096,-0.569222937,0.822181587,0.000899936],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p28 := [[13.4510,-0.6428,-4.1894],[0.001661013,-0.569518616,0.821976013,0.001104542],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p29 := [[14.1542,-0.5053,-4.5968],[0.001816934,-0.569666719,0.821872893,0.001214702],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p30 := [[15.5772,-0.1839,-5.4680],[0.002149687,-0.569963438,0.821665962,0.001450753],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p31 := [[16.2972,0.0000,-5.9317],[0.002326513,-0.570112047,0.821562143,0.001576651],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p32 := [[16.2972,0.0000,-5.9317],[0.002326513,-0.570112047,0.821562143,0.001576651],[-2,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

  PROC main()
    ! ---- phase: approach
    MoveJ p1,v100,fine,tFSW\WObj:=wSeam;
    MoveL p2,vS1,fine,tFSW\WObj:=wSeam;
    MoveL p3,vS1,fine,tFSW\WObj:=wSeam;
    MoveL p4,vS1,fine,tFSW\WObj:=wSeam;
    MoveL p5,vS1,fine,tFSW\WObj:=wSeam;
    MoveL p6,vS1,fine,tFSW\WObj:=wSeam;
    ! ---- phase: plunge
    ! SPINDLE START placeholder: e.g. SetDO doSpindle, 1;
    ! WaitDI diSpindleAtSpeed, 1;
    WaitTime\InPos,0.600;
    ! ---- phase: dwell
    WaitTime\InPos,0.600;
    ! ---- phase: accelerate
    MoveL p9,vS2,fine,tFSW\WObj:=wSeam;
    MoveL p10,vS3,zB1,tFSW\WObj:=wSeam;
    MoveL p11,vS4,zB2,tFSW\WObj:=wSeam;
    ! ---- phase: weld
    MoveL p12,vS5,zB3,tFSW\WObj:=wSeam;
    MoveL p13,vS6,zB4,tFSW\WObj:=wSeam;
    MoveL p14,vS7,zB5,tFSW\WObj:=wSeam;
    MoveL p15,vS8,zB6,tFSW\WObj:=wSeam;
    MoveL p16,vS9,zB7,tFSW\WObj:=wSeam;
    MoveL p17,vS10,zB8,tFSW\WObj:=wSeam;
    MoveL p18,vS11,zB9,tFSW\WObj:=wSeam;
    MoveL p19,vS12,zB10,tFSW\WObj:=wSeam;
    MoveL p20,vS13,zB11,tFSW\WObj:=wSeam;
    MoveL p21,vS14,zB12,tFSW\WObj:=wSeam;
    MoveL p22,vS15,zB13,tFSW\WObj:=wSeam;
    MoveL p23,vS16,zB14,tFSW\WObj:=wSeam;
    MoveL p24,vS17,zB15,tFSW\WObj:=wSeam;
    MoveL p25,vS18,zB16,tFSW\WObj:=wSeam;
    MoveL p26,vS19,zB17,tFSW\WObj:=wSeam;
    MoveL p27,vS20,zB18,tFSW\WObj:=wSeam;
    MoveL p28,vS21,zB19,tFSW\WObj:=wSeam;
    MoveL p29,vS22,zB19,tFSW\WObj:=wSeam;
    ! ---- phase: decelerate
    MoveL p30,vS23,zB20,tFSW\WObj:=wSeam;
    MoveL p31,vS24,fine,tFSW\WObj:=wSeam;
    ! ---- phase: retract
    ! SPINDLE STOP placeholder: e.g. SetDO doSpindle, 0;
    WaitTime\InPos,0.600;
  ENDPROC
ENDMODULE
