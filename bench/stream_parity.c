/* Eight streams walked in lockstep, as the AVX-512 kernels' slots and lanes
 * do (docs/benchmarks.md, session 26): segment k of 10^7 float64 samples
 * copied one line per step (a 64-byte load of z, streamed stores of x and
 * 2z), the segments' starting lines shifted so that the parities of their
 * current lines follow a pattern. With AVX-512 a line is one 64-byte load
 * and store; on AVX2-only CPUs (built with -march=native there) two 32-byte
 * halves, as the AVX2 kernels store them.
 *
 *   gcc -O3 -march=native bench/stream_parity.c -o /tmp/stream_parity
 *   /tmp/stream_parity
 *
 * On the AVX-512 Xeon guest (session 26), ns per sample: odd distances
 * (and the patterns 0 1 0 1 ..., 0..7) 0.78-0.82; all one parity,
 * 0 0 0 0 1 1 1 1 and 0 2 4 6 ... 0.95-1.01; 0 0 1 1 ... 0.84.
 */
#include <immintrin.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static double now(void){struct timespec t;clock_gettime(CLOCK_MONOTONIC,&t);return t.tv_sec+1e-9*t.tv_nsec;}
__attribute__((noinline)) static void walk(const double*z,double*x,double*v,long len,const long*st){
  for(long i=0;i<len;i+=8){
    for(int k=0;k<8;k++){
      long o=st[k]+i;
#ifdef __AVX512F__
      __m512d a=_mm512_loadu_pd(z+o);
      _mm512_stream_pd(x+o,a);
      _mm512_stream_pd(v+o,_mm512_add_pd(a,a));
#else
      __m256d a=_mm256_loadu_pd(z+o), b=_mm256_loadu_pd(z+o+4);
      _mm256_stream_pd(x+o,a);
      _mm256_stream_pd(x+o+4,b);
      _mm256_stream_pd(v+o,_mm256_add_pd(a,a));
      _mm256_stream_pd(v+o+4,_mm256_add_pd(b,b));
#endif
    }
  }
  _mm_sfence();
}
int main(void){
  const long N=10600000, S=1250000, len=S-64; const int reps=7;
  double*z=aligned_alloc(1<<21,N*8),*x=aligned_alloc(1<<21,N*8),*v=aligned_alloc(1<<21,N*8);
  if(!z||!x||!v) return 1;
  for(long i=0;i<N;i++){z[i]=i;x[i]=0;v[i]=0;}
  const char*names[]={"same parity (distance 156,250 lines)","0 1 0 1 0 1 0 1","0 0 1 1 0 0 1 1","0 0 0 0 1 1 1 1","0 1 2 3 4 5 6 7","0 2 4 6 0 2 4 6","odd distance (156,251 lines)"};
  const int pats[6][8]={{0,0,0,0,0,0,0,0},{0,1,0,1,0,1,0,1},{0,0,1,1,0,0,1,1},{0,0,0,0,1,1,1,1},{0,1,2,3,4,5,6,7},{0,2,4,6,0,2,4,6}};
  for(int p=0;p<7;p++){
    long st[8];
    for(int k=0;k<8;k++) st[k]= p<6 ? k*S+8*pats[p][k] : k*(S+8);
    double best=1e9;
    for(int r=0;r<reps;r++){double t0=now(); walk(z,x,v,len,st); double t=now()-t0; if(t<best)best=t;}
    printf("%-40s %.3f ns per sample\n",names[p],best/(len*8)*1e9);
  }
  return 0;
}
