// A four-tendon rig (the spatial twin's arm with four tendons): four steppers on the stepper board, four load
// cells on the DAQ board, each axis with the paper's travel and speed. The DAQ link runs at 1 Mbaud: four
// channels at 1 kHz need up to 640 kbit/s in the text framing (PROTOCOL.md, "Link budget"). RIG_HASH is a
// placeholder (no rig file behind it).
#ifndef RIG_CONFIG_FOUR_TENDON_H
#define RIG_CONFIG_FOUR_TENDON_H

#define RIG_HASH "00000004"
#define RIG_NAME "four_tendon"
#define RIG_AXES 4
#define RIG_CHANNELS 4
#define RIG_MIN_INTERVAL_US 639
#define RIG_MAX_INTERVAL_US 1000000L
#define RIG_AXIS_TRAVEL_STEPS {156, 156, 156, 156}
#define RIG_PROGRAMME_MAX 64
#define RIG_DAQ_RATE_MIN_HZ 100
#define RIG_DAQ_RATE_MAX_HZ 2000
#define RIG_DAQ_RATE_DEFAULT_HZ 1000
#define RIG_DAQ_BAUD 1000000L
#define RIG_STEPPER_BAUD 115200L
#define RIG_ADC_CLIP_LOW_COUNTS 116
#define RIG_ADC_CLIP_HIGH_COUNTS 628

#endif
