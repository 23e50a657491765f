/* The compute floor of float32 rows in float64 arithmetic with AVX-512
 * (docs/benchmarks.md, session 27): G groups of eight rows, each group one
 * dependency chain of eight slots, blocks of 16 samples per row: eight
 * 64-byte loads, the 8 x 16 float32 transpose of the kernels
 * (`simd::transpose8x16`), widening to float64, 16 alpha-beta steps with
 * FMA (the kernels' `clean_step8`), narrowing and the transposes back,
 * sixteen 64-byte stores. Rows of N samples in the caches: no memory
 * traffic, no start-ups, no events: only the block arithmetic.
 *
 *   for g in 1 2 3 4; do gcc -O3 -march=native -DG=$g bench/f32_block_floor.c -o /tmp/fbf$g; /tmp/fbf$g 1024 2000; done
 *
 * On the AVX-512 Xeon guest (session 27), ns per sample: G=1 0.475 (the
 * row lanes' 0.48-0.50 on long rows in L2), G=2 0.410, G=3 0.412, G=4
 * 0.473; the float32 ceiling of bench/run.py (a streamed C copy) is
 * ~0.5 ns per sample there.
 */
#include <immintrin.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#ifndef G
#define G 1
#endif
static inline void tr8x16(__m512 r[8]) {
  __m512d a01=_mm512_castps_pd(_mm512_unpacklo_ps(r[0],r[1])), b01=_mm512_castps_pd(_mm512_unpackhi_ps(r[0],r[1]));
  __m512d a23=_mm512_castps_pd(_mm512_unpacklo_ps(r[2],r[3])), b23=_mm512_castps_pd(_mm512_unpackhi_ps(r[2],r[3]));
  __m512d a45=_mm512_castps_pd(_mm512_unpacklo_ps(r[4],r[5])), b45=_mm512_castps_pd(_mm512_unpackhi_ps(r[4],r[5]));
  __m512d a67=_mm512_castps_pd(_mm512_unpacklo_ps(r[6],r[7])), b67=_mm512_castps_pd(_mm512_unpackhi_ps(r[6],r[7]));
  __m512d t[4]={_mm512_unpacklo_pd(a01,a23),_mm512_unpackhi_pd(a01,a23),_mm512_unpacklo_pd(b01,b23),_mm512_unpackhi_pd(b01,b23)};
  __m512d u[4]={_mm512_unpacklo_pd(a45,a67),_mm512_unpackhi_pd(a45,a67),_mm512_unpacklo_pd(b45,b67),_mm512_unpackhi_pd(b45,b67)};
  __m512i ip=_mm512_set_epi64(11,10,3,2,9,8,1,0), iq=_mm512_set_epi64(15,14,7,6,13,12,5,4);
  for(int j=0;j<4;j++){ r[j]=_mm512_castpd_ps(_mm512_permutex2var_pd(t[j],ip,u[j])); r[4+j]=_mm512_castpd_ps(_mm512_permutex2var_pd(t[j],iq,u[j])); }
}
static inline void untr8x16(__m512 r[8]) {
  __m512i it=_mm512_set_epi64(13,12,9,8,5,4,1,0), iu=_mm512_set_epi64(15,14,11,10,7,6,3,2);
  __m512d t[4],u[4];
  for(int j=0;j<4;j++){ t[j]=_mm512_permutex2var_pd(_mm512_castps_pd(r[j]),it,_mm512_castps_pd(r[4+j])); u[j]=_mm512_permutex2var_pd(_mm512_castps_pd(r[j]),iu,_mm512_castps_pd(r[4+j])); }
  __m512 a01=_mm512_castpd_ps(_mm512_unpacklo_pd(t[0],t[1])), a23=_mm512_castpd_ps(_mm512_unpackhi_pd(t[0],t[1]));
  __m512 b01=_mm512_castpd_ps(_mm512_unpacklo_pd(t[2],t[3])), b23=_mm512_castpd_ps(_mm512_unpackhi_pd(t[2],t[3]));
  __m512 a45=_mm512_castpd_ps(_mm512_unpacklo_pd(u[0],u[1])), a67=_mm512_castpd_ps(_mm512_unpackhi_pd(u[0],u[1]));
  __m512 b45=_mm512_castpd_ps(_mm512_unpacklo_pd(u[2],u[3])), b67=_mm512_castpd_ps(_mm512_unpackhi_pd(u[2],u[3]));
  r[0]=_mm512_shuffle_ps(a01,b01,0x88); r[1]=_mm512_shuffle_ps(a01,b01,0xdd);
  r[2]=_mm512_shuffle_ps(a23,b23,0x88); r[3]=_mm512_shuffle_ps(a23,b23,0xdd);
  r[4]=_mm512_shuffle_ps(a45,b45,0x88); r[5]=_mm512_shuffle_ps(a45,b45,0xdd);
  r[6]=_mm512_shuffle_ps(a67,b67,0x88); r[7]=_mm512_shuffle_ps(a67,b67,0xdd);
}
static inline __m512d widen(__m512 r[8], int s){ __m512 v=r[(s/8)*4+s%4]; __m256 h=((s/4)%2==0)?_mm512_castps512_ps256(v):_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(v),1)); return _mm512_cvtps_pd(h);}
static inline __m512 pair(__m512d lo, __m512d hi){ return _mm512_castpd_ps(_mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_castps_pd(_mm512_cvtpd_ps(lo))), _mm256_castps_pd(_mm512_cvtpd_ps(hi)),1)); }
// rows: G*8 rows of length n at stride n; process samples [0, nb*16)
__attribute__((noinline)) void kern(const float* z, float* x, float* v, long n, long nb, double* st) {
  __m512d ct=_mm512_set1_pd(0.1), ca=_mm512_set1_pd(0.5), coma=_mm512_set1_pd(0.5), cg2=_mm512_set1_pd(2.0);
  __m512d xv[G], vv[G];
  for(int g=0;g<G;g++){ xv[g]=_mm512_loadu_pd(st+16*g); vv[g]=_mm512_loadu_pd(st+16*g+8); }
  for(long b=0;b<nb;b++){
    long o=b*16;
    __m512 r[G][8];
    __m512d xo[G][16], vo[G][16];
    for(int g=0;g<G;g++){ for(int l=0;l<8;l++) r[g][l]=_mm512_loadu_ps(z+(g*8+l)*n+o); tr8x16(r[g]); }
    for(int j=0;j<16;j++){
      for(int g=0;g<G;g++){
        __m512d zj=widen(r[g],j);
        __m512d xp=_mm512_fmadd_pd(ct,vv[g],xv[g]);
        __m512d w=_mm512_fmadd_pd(cg2,zj,vv[g]);
        xv[g]=_mm512_fmadd_pd(coma,xp,_mm512_mul_pd(ca,zj));
        vv[g]=_mm512_fnmadd_pd(cg2,xp,w);
        xo[g][j]=xv[g]; vo[g][j]=vv[g];
      }
    }
    for(int g=0;g<G;g++){
      __m512 xl[8], vl[8];
      for(int i=0;i<8;i++){ int h=i/4,j=i%4; xl[i]=pair(xo[g][h*8+j],xo[g][h*8+4+j]); vl[i]=pair(vo[g][h*8+j],vo[g][h*8+4+j]); }
      untr8x16(xl); untr8x16(vl);
      for(int l=0;l<8;l++){ _mm512_storeu_ps(x+(g*8+l)*n+o,xl[l]); _mm512_storeu_ps(v+(g*8+l)*n+o,vl[l]); }
    }
  }
  for(int g=0;g<G;g++){ _mm512_storeu_pd(st+16*g,xv[g]); _mm512_storeu_pd(st+16*g+8,vv[g]); }
}
int main(int argc,char**argv){
  long n=atol(argv[1]); long reps=atol(argv[2]);
  long rows=8*G; long nb=n/16;
  float*z=aligned_alloc(64,rows*n*4),*x=aligned_alloc(64,rows*n*4),*v=aligned_alloc(64,rows*n*4);
  for(long i=0;i<rows*n;i++) z[i]=(i%n)*0.7f+(i*7919%13)*0.1f;
  double st[64]={0};
  double best=1e9;
  for(int k=0;k<5;k++){ struct timespec a,b; clock_gettime(CLOCK_MONOTONIC,&a);
    for(long r=0;r<reps;r++) kern(z,x,v,n,nb,st);
    clock_gettime(CLOCK_MONOTONIC,&b); double t=(b.tv_sec-a.tv_sec)*1e9+(b.tv_nsec-a.tv_nsec); if(t<best)best=t; }
  printf("G=%d n=%ld: %.3f ns/sample (%.2f cycles @4GHz)\n",G,n,best/(reps*rows*nb*16.0),best/(reps*rows*nb*16.0)*4);
  return (int)st[3];
}
